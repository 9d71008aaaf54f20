"""The Wireshark dissector, generated from the catalog.

`generate_dissector()` returns a Lua file made of two parts: a table generated here from the
catalog's public objects (every command of every dialect, its forms, fields, codecs, units,
enum tables, the documented ports), and the fixed runtime in `dissector_runtime.lua` (a port of
`FrameParser`'s scanning rules, one decoder per codec class, tree and column building). Nothing
about individual commands is written by hand on the Lua side.

A codec class the generator does not know raises `DissectorError` naming it, so a new codec kind
in the catalog is noticed (and taught to the runtime) instead of being silently shown as raw.
"""

from __future__ import annotations

import re
from collections.abc import Iterable
from importlib import resources
from typing import Any

from ..protocol import (
    DIALECT_NAMES,
    REQUEST,
    RESPONSE,
    CommandSpec,
    DeviceModel,
    Dialect,
    FrameParser,
    all_models,
    dialect_for,
    get_dialect,
)
from ..protocol import frame as frame_module
from ..protocol.fields import Codec, Enum
from ..protocol.fields.base import decimals_of
from ..protocol.frame import ADDRESS_NAMES, DEVICE_ADDRESSES, HOST_ADDRESSES, MAX_LENGTH
from .heuristic import lua_table as heuristic_rule
from .lua import DissectorError, to_lua
from .ports import documented_ports

# Codec kinds whose decoded value is a number (their Wireshark fields are FT_DOUBLE).
NUMERIC_KINDS = frozenset({"number", "coordinate"})
# strptime directives the runtime's timestamp decoder handles: (name, width). `%f2` is the
# catalog's "hundredths of a second".
_TIME_DIRECTIVES = {"%Y": 4, "%y": 2, "%m": 2, "%d": 2, "%H": 2, "%M": 2, "%S": 2, "%f2": 2}


# -- codecs ------------------------------------------------------------------------------------


def _exact_divisor(scale: float) -> int:
    """1/scale when that is a whole number (values are then divided, which is exact)."""
    inv = 1 / scale
    return round(inv) if scale < 1 and abs(inv - round(inv)) < 1e-9 else 0


def _time_segments(layout: str) -> list[Any]:
    out: list[Any] = []
    i = 0
    while i < len(layout):
        if layout[i] == "%":
            d = layout[i : i + 3] if layout[i : i + 3] == "%f2" else layout[i : i + 2]
            if d not in _TIME_DIRECTIVES:
                raise DissectorError(f"timestamp layout {layout!r}: directive {d!r} is unknown to the dissector")
            out.append({"d": d[1:], "w": _TIME_DIRECTIVES[d]})
            i += len(d)
        else:
            out.append({"lit": layout[i].encode("latin-1")})
            i += 1
    return out


def _enum_map(codec: Enum) -> dict[bytes, dict[str, str | None]]:
    table: dict[bytes, dict[str, str | None]] = {}
    for v in codec.values:
        entry = {"name": v.name, "label": v.label, "term": v.vendor_term or None}
        table[v.raw.encode("latin-1")] = entry
        table.setdefault(v.raw.lower().encode("latin-1"), entry)  # some firmware spells hex in lower case
    return table


def codec_entry(codec: Codec, where: str) -> dict[str, Any]:
    """What the Lua runtime needs to decode one codec, from its public attributes (`describe()`
    names the class; the families' stable attributes give the layout)."""
    cls, kind = type(codec).__name__, codec.kind  # describe()["codec"] names the class the same way
    c: dict[str, Any] = {"unit": codec.unit}
    a: Any = codec  # the attributes read below are each family's documented public ones
    if cls == "HexInt" and kind == "number":
        c.update(k="hex", w=a.width, signed=bool(a.signed), scale=a.scale, div=_exact_divisor(a.scale))
        c.update(dec=decimals_of(a.scale), int=a.scale == 1, none=list(a.none_tokens))
    elif cls == "DecInt" and kind == "number":
        c.update(k="dec", w=a.width, scale=a.scale, dec=decimals_of(a.scale), int=a.scale == 1)
    elif cls == "DecFloat" and kind == "number":
        c.update(k="float", w=a.width, decimals=a.decimals, none=list(a.none_tokens))
    elif cls == "BinInt" and kind == "number":
        c.update(k="bin", w=a.width, signed=bool(a.signed), little=a.byteorder == "little")
        c.update(scale=a.scale, dec=decimals_of(a.scale), int=a.scale == 1)
    elif cls == "Bitrate" and kind == "number":
        c.update(k="bitrate", int=True)
    elif cls == "Enum" and kind == "enum":
        c.update(k="enum", w=a.width, map=_enum_map(a))
    elif cls == "OneOf" and kind == "enum_or_number":
        c.update(k="oneof", w=a.width, tokens=codec_entry(a.tokens, where), number=codec_entry(a.number, where))
    elif cls == "Text" and kind == "text":
        c.update(k="text", min=a.min_width, max=a.max_width)
    elif cls == "IPv4Text" and kind == "ipv4":
        c.update(k="ipv4")
    elif cls == "RawData" and kind == "raw":
        c.update(k="raw", w=a.width)
    elif cls == "Literal" and kind == "literal":
        c.update(k="literal", text=a.text.encode("latin-1"))
    elif cls == "Geo" and kind == "coordinate":
        if a.style not in ("dm", "deg") or a.axis not in ("lat", "lon"):
            raise DissectorError(f"{where}: Geo style {a.style!r} axis {a.axis!r} is unknown to the dissector")
        c.update(k="geo", axis=a.axis, style=a.style, limit=a.limit)
    elif cls == "Timestamp" and kind == "datetime":
        c.update(k="time", segments=_time_segments(a.layout))
    else:
        raise DissectorError(
            f"{where}: codec {cls} (kind {kind!r}) is unknown to the dissector generator; "
            "teach topgimbal/wire/dissector.py and dissector_runtime.lua to decode it"
        )
    c["numeric"] = kind in NUMERIC_KINDS
    return c


# -- catalog -> tables ---------------------------------------------------------------------------

_UNIT_SUFFIX = re.compile(r"[^a-z0-9]+")


def short_name(name: str, unit: str) -> str:
    """A field's name without its unit suffix, for the Info column (`yaw_deg` -> `yaw`)."""
    if unit:
        suffix = "_" + _UNIT_SUFFIX.sub("_", unit.lower()).strip("_")
        if name.endswith(suffix) and len(name) > len(suffix):
            return name[: -len(suffix)]
    return name


class _Codecs:
    """Codec entries shared by reference (many fields use the same codec)."""

    def __init__(self) -> None:
        self.entries: list[dict[str, Any]] = []
        self._index: dict[str, int] = {}

    def add(self, codec: Codec, where: str) -> int:
        entry = codec_entry(codec, where)
        key = to_lua(entry)
        if key not in self._index:
            self.entries.append(entry)
            self._index[key] = len(self.entries)
        return self._index[key]


def _command(spec: CommandSpec, codecs: _Codecs, dialect: str) -> dict[str, Any]:
    forms = []
    for form in spec.forms:
        fields = []
        at: int | None = 0
        for f in form.fields:
            where = f"{dialect} {spec.ident} field {f.name}"
            w = f.codec.width
            end = at + w if (w is not None and at is not None) else None  # None: the rest of the data
            fields.append(
                {
                    "n": f.name,
                    "c": codecs.add(f.codec, where),
                    "a": at,
                    "b": end,
                    "s": short_name(f.name, f.codec.unit),
                    "d": f.description,
                }
            )
            at = end
        forms.append(
            {
                "rw": form.rw,
                "dir": form.direction,
                "title": form.title,
                "role": form.role,
                "const": form.const,
                "min": form.min_length,
                "max": form.max_length,
                "fields": fields,
            }
        )
    return {"name": spec.name, "title": spec.title, "forms": forms}


def _index(spec: CommandSpec) -> dict[str, list[int]]:
    """(rw, direction) -> forms to try, 1-based: the direction's own forms first, then the other
    direction's (frames whose addresses are not swapped); the order the Python decoder uses."""
    out: dict[str, list[int]] = {}
    pos = {id(f): i + 1 for i, f in enumerate(spec.forms)}
    for rw in ("r", "w"):
        for direction, other in ((REQUEST, RESPONSE), (RESPONSE, REQUEST)):
            forms = spec.forms_for(rw, direction) + spec.forms_for(rw, other)
            if forms:
                out[f"{rw}|{direction}"] = [pos[id(f)] for f in forms]
    return out


def _dialect(d: Dialect, codecs: _Codecs) -> dict[str, Any]:
    commands = {}
    index = {}
    for ident in sorted(d.commands):
        spec = d.commands[ident]
        commands[ident] = _command(spec, codecs, d.name)
        for key, forms in _index(spec).items():
            index[f"{ident}|{key}"] = forms
    return {
        "title": d.title,
        "headers": list(d.headers),
        "hosts": d.host_addresses,
        "commands": commands,
        "index": index,
    }


def _variant(base: dict[str, Any], model: DeviceModel, codecs: _Codecs) -> dict[str, Any] | None:
    """The commands a model's own dialect (its `dialect_options`: the C11's 0.5 deg/s rate step)
    decodes differently from the document's defaults, or None when it decodes none differently."""
    own = _dialect(dialect_for(model), codecs)
    changed = sorted(i for i, cmd in own["commands"].items() if to_lua(cmd) != to_lua(base["commands"].get(i)))
    if not changed:
        return None
    index = {k: v for k, v in own["index"].items() if k.split("|", 1)[0] in changed}
    return {"commands": {i: own["commands"][i] for i in changed}, "index": index}


def _models(tables: dict[str, Any], codecs: _Codecs) -> tuple[list[dict[str, Any]], dict[str, Any]]:
    """Every model (the Model preference) and the variants some models' dialects need: a model
    with no variant decodes with its dialect's defaults."""
    models: list[dict[str, Any]] = []
    variants: dict[str, Any] = {}
    seen: dict[str, str] = {}  # a variant's Lua text -> the first model that has it
    for name, model in all_models().items():
        if model.dialect not in tables:
            continue
        variant = _variant(tables[model.dialect], model, codecs)
        key = None
        if variant is not None:
            text = to_lua(variant)
            key = seen.setdefault(text, name)
            variants.setdefault(key, variant)
        models.append({"name": name, "dialect": model.dialect, "variant": key})
    return models, variants


def _field_types(tables: Iterable[dict[str, Any]], codecs: list[dict[str, Any]]) -> dict[str, str]:
    """Every field name -> "double" when all its codecs decode to numbers, else "string"."""
    kinds: dict[str, set[bool]] = {}
    for table in tables:
        for cmd in table["commands"].values():
            for form in cmd["forms"]:
                for f in form["fields"]:
                    kinds.setdefault(f["n"], set()).add(codecs[f["c"] - 1]["numeric"])
    return {name: ("double" if k == {True} else "string") for name, k in sorted(kinds.items())}


def catalog_tables(dialect_names: Iterable[str] = DIALECT_NAMES) -> dict[str, Any]:
    """Everything the Lua runtime reads, as data."""
    dialects = [get_dialect(n) for n in dialect_names]
    codecs = _Codecs()
    tables = {d.name: _dialect(d, codecs) for d in dialects}
    models, variants = _models(tables, codecs)
    ports: dict[str, dict[int, str]] = {"udp": {}, "tcp": {}}
    for (transport, port), name in sorted(documented_ports().items()):
        if name in tables:
            ports[transport][port] = name
    return {
        # The parser takes only 3 ASCII letters or digits as an identifier (and lets a valid frame
        # starting inside a chance checksum match win) once protocol.frame has is_identifier.
        "strict_identifier": hasattr(frame_module, "is_identifier"),
        "dialect_order": [d.name for d in dialects],
        "addresses": dict(ADDRESS_NAMES),
        "device_addresses": DEVICE_ADDRESSES,
        "host_addresses": HOST_ADDRESSES,
        "max_ascii_length": MAX_LENGTH["#TP"],
        "max_data_length": FrameParser().max_data_length,
        "ports": ports,
        "heuristic": heuristic_rule(),  # the same rule as decode --pcap (heuristic.py)
        "field_types": _field_types([*tables.values(), *variants.values()], codecs.entries),
        "codecs": codecs.entries,
        "dialects": tables,
        "models": models,
        "variants": variants,
    }


HEADER = """\
-- topgimbal.lua: Wireshark dissector for the TOP gimbal-camera protocol
-- (SkyDroid C10/C10Pro/C11/C12/C13/C20 and TOPOTEK SIP).
--
-- GENERATED by `topgimbal dissector` from the topgimbal catalog: do not edit by hand.
-- Install: copy into your personal Lua plugins folder (see docs/wireshark.md), or run
--   tshark -X lua_script:topgimbal.lua -r capture.pcap
-- Filter fields start with `top.` (top.id == "GAC", top.checksum.status == 0, top.field.yaw_deg > 10).
-- Preferences: top.model (a device model, e.g. C11), top.dialect (skydroid, topotek); both auto
-- by default (documented port, else the frame). Runs on Lua 5.2, 5.3 and 5.4.
"""


def _source(name: str) -> str:
    return resources.files(__package__).joinpath(name).read_text(encoding="utf-8")


def core_source() -> str:
    """The pure Lua core (scanner, codec decoders, dialect choice): no Wireshark API, it expects
    the generated `GEN` table before it and leaves its functions in the local table `CORE`."""
    return _source("dissector_core.lua")


def runtime_source() -> str:
    """The fixed Lua runtime: the core followed by the Wireshark glue (shipped with the package)."""
    return core_source() + "\n" + _source("dissector_runtime.lua")


def generated_tables(dialect_names: Iterable[str] = DIALECT_NAMES) -> str:
    """`local GEN = {...}`: the catalog as the Lua runtime reads it."""
    return "local GEN = " + to_lua(catalog_tables(dialect_names)) + "\n"


def generate_dissector(dialect_names: Iterable[str] = DIALECT_NAMES) -> str:
    """The whole dissector: generated tables followed by the runtime."""
    return HEADER + "\n" + generated_tables(dialect_names) + "\n" + runtime_source()
