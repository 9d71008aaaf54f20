"""MAVLink camera definitions (the XML ground stations read for a camera's settings), generated
from the catalog: pure, no I/O.

A setting is one field of a stored setting the model supports (a command of the camera or thermal
group that a host can write, not the photo and recording actions MAVLink has commands for): its
enum values become options (English labels, the vendor's Chinese terms as a zh_CN localization),
its numeric range min / max / step. A write form's fields with a catalog default are not settings
(they select a lens or say "no change") and are sent with that default. A command of several
settings is offered only where the camera can be read (a write must carry the others' current
values). The camera group belongs to the visible lens, the thermal group to the thermal lens:
each lens (a camera component) has its own file, so a thermal setting is never offered for the
visible lens. The version is a digest of the definition's content: it changes when the catalog
does, which is what tells a ground station to fetch the file again."""

from __future__ import annotations

import zlib
from dataclasses import dataclass
from typing import Any
from xml.sax.saxutils import quoteattr

from ..protocol import DeviceModel, Dialect
from ..protocol.commands import CommandSpec, factory_values, stored_form

LENS_GROUPS = {"visible": ("camera",), "thermal": ("thermal",)}
ACTION_ROLES = frozenset({"photo", "recording"})  # MAVLink commands, not settings
MAX_PARAM_ID = 16  # PARAM_EXT param_id is char[16]
INT32 = (-(2**31), 2**31 - 1)


@dataclass(frozen=True)
class Option:
    value: int  # the PARAM_EXT value
    name: str  # the catalog's enum name (what the client API takes)
    label: str  # English
    vendor_term: str  # the vendor's own (Chinese) term, "" when the catalog has none


@dataclass(frozen=True)
class Setting:
    param: str  # PARAM_EXT id
    ident: str  # catalog command
    field: str  # the field of its write form
    title: str
    lens: str
    type: str  # MAVLink definition type: uint8, int32 or float
    default: float
    options: tuple[Option, ...] = ()
    min: float | None = None
    max: float | None = None
    step: float | None = None
    unit: str = ""
    fixed: tuple[tuple[str, Any], ...] = ()  # write-form fields sent with their catalog default
    siblings: tuple[str, ...] = ()  # the other settings of the same command (filled from a read)
    readable: bool = False  # the camera can say its current value

    @property
    def wire_type(self) -> int:
        """MAV_PARAM_EXT_TYPE."""
        return {"uint8": 1, "int32": 6, "float": 9}[self.type]

    def option(self, value: float) -> Option | None:
        return next((o for o in self.options if o.value == value), None)

    def to_api(self, value: float) -> Any:
        """A PARAM_EXT value as the catalog field's value (enum name or number); ValueError when
        the value is not one this setting takes."""
        if self.options:
            o = self.option(value)
            if o is None:
                raise ValueError(f"{value:g} is not an option of {self.param} ({self.allowed()})")
            return o.name
        if self.min is not None and not self.min <= value <= self.max:  # type: ignore[operator]
            raise ValueError(f"{value:g} is out of {self.param}'s range ({self.allowed()})")
        if self.type != "float":
            if value != int(value):
                raise ValueError(f"{value:g}: {self.param} takes whole numbers")
            return int(value)
        return float(value)

    def from_api(self, value: Any) -> float | None:
        """A catalog field's value as the PARAM_EXT value (None: not one of the options)."""
        if self.options:
            o = next((o for o in self.options if o.name == value), None)
            return None if o is None else float(o.value)
        try:
            return float(value)
        except (TypeError, ValueError):
            return None

    def allowed(self) -> str:
        if self.options:
            return ", ".join(f"{o.value} {o.label}" for o in self.options)
        return f"{self.min:g}..{self.max:g}" + (f" in steps of {self.step:g}" if self.step else "")


def _options(values: list[dict[str, Any]]) -> tuple[Option, ...]:
    # next / previous / toggle are not values, nor the "no change" marker (`null`)
    plain = [v for v in values if v.get("idempotent", True) and v["name"] != "null"]
    try:
        codes = [int(v["raw"], 16) for v in plain]
    except ValueError:
        codes = []
    if len(set(codes)) != len(plain):
        codes = list(range(len(plain)))  # raw codes that are not numbers: the catalog's order
    return tuple(Option(c, v["name"], v.get("label") or v["name"], v.get("vendor_term") or "")
                 for c, v in zip(codes, plain, strict=True))  # fmt: skip


def _query_free(spec: CommandSpec) -> bool:
    """Whether the camera can be asked the whole setting without saying which part (a query
    whose fields all have defaults)."""
    forms = spec.forms_for("r", "request")
    return bool(forms) and any(all(f.default is not None for f in form.fields) for form in forms)


def _param_id(ident: str, field: str, taken: set[str]) -> str:
    base = f"{ident}_{field}".upper()[:MAX_PARAM_ID]
    name, n = base, 1
    while name in taken:
        n += 1
        name = f"{base[: MAX_PARAM_ID - len(str(n))]}{n}"
    taken.add(name)
    return name


def _spec_settings(spec: CommandSpec, lens: str, taken: set[str]) -> list[Setting]:
    forms = spec.forms_for("w", "request")
    if not forms:
        return []
    form = forms[0].describe()
    stored = stored_form(spec)
    stored_names = {f.name for f in stored.fields} if stored is not None else set()
    factory = factory_values(spec)
    chosen, fixed = [], []
    for f in form["fields"]:
        if f.get("default") is not None:
            fixed.append((f["name"], f["default"]))
        elif (f["kind"] == "enum" and f.get("values")) or (f["kind"] == "number" and "min" in f):
            chosen.append(f)
        else:
            return []  # raw data, text...: nothing a settings screen can offer
    readable = _query_free(spec) and all(f["name"] in stored_names for f in chosen)
    if not chosen or (len(chosen) > 1 and not readable):
        return []
    out: list[Setting] = []
    params = [_param_id(spec.ident, f["name"], taken) for f in chosen]
    for f, param in zip(chosen, params, strict=True):
        siblings = tuple(p for p in params if p != param)
        common: dict[str, Any] = dict(param=param, ident=spec.ident, field=f["name"], title=spec.title, lens=lens, unit=f.get("unit", ""),
                      fixed=tuple(fixed), siblings=siblings, readable=readable)  # fmt: skip
        if f["kind"] == "enum":
            options = _options(f["values"])
            if not options:
                return []
            first = factory.get(f["name"])
            default = float(next((o.value for o in options if o.name == first), options[0].value))
            typ = "uint8" if max(o.value for o in options) < 256 else "int32"
            out.append(Setting(type=typ, default=default, options=options, **common))
            continue
        lo, hi, step = float(f["min"]), float(f["max"]), float(f.get("step") or 0)
        whole = step == int(step) and step >= 1 and lo == int(lo) and INT32[0] <= lo and hi <= INT32[1]
        default = float(factory.get(f["name"], lo)) if isinstance(factory.get(f["name"]), (int, float)) else lo
        out.append(Setting(type="int32" if whole else "float", default=min(max(default, lo), hi), min=lo, max=hi,
                           step=step or None, **common))  # fmt: skip
    return out


def settings_for(dialect: Dialect, model: DeviceModel, lens: str) -> list[Setting]:
    """The settings one lens of the model offers, in catalog order."""
    if lens == "thermal" and not model.thermal:
        return []
    groups = LENS_GROUPS[lens]
    taken: set[str] = set()
    out: list[Setting] = []
    for spec in dialect.supported(model):
        if spec.group in groups and spec.writable and not spec.motion and spec.role not in ACTION_ROLES:
            out.extend(_spec_settings(spec, lens, taken))
    return out


def _fmt(x: float) -> str:
    return str(int(x)) if x == int(x) else repr(float(x))


def _body(vendor: str, model_name: str, settings: list[Setting], version: int) -> str:
    q = quoteattr
    out = ['<?xml version="1.0" encoding="UTF-8"?>',
           "<!-- Generated from the topgimbal catalog (topgimbal camdef): do not edit. -->",
           "<mavlinkcamera>", f'  <definition version="{version}">', f"    <model>{_esc(model_name)}</model>",
           f"    <vendor>{_esc(vendor)}</vendor>", "  </definition>", "  <parameters>"]  # fmt: skip
    terms: dict[str, str] = {}
    for s in settings:
        attrs = f"name={q(s.param)} type={q(s.type)} default={q(_fmt(s.default))}"
        if s.min is not None and s.max is not None:
            attrs += f" min={q(_fmt(s.min))} max={q(_fmt(s.max))}"
        if s.step:
            attrs += f" step={q(_fmt(s.step))}"
        out.append(f"    <parameter {attrs}>")
        unit = f" ({s.unit})" if s.unit else ""
        out.append(f"      <description>{_esc(s.title + ': ' + s.field.replace('_', ' ') + unit)}</description>")
        if s.options:
            out.append("      <options>")
            for o in s.options:
                out.append(f"        <option name={q(o.label)} value={q(str(o.value))}/>")
                if o.vendor_term:
                    terms.setdefault(o.label, o.vendor_term)
            out.append("      </options>")
        out.append("    </parameter>")
    out.append("  </parameters>")
    if terms:
        out += ["  <localization>", '    <locale name="zh_CN">']
        out += [f"      <strings original={q(k)} translated={q(v)}/>" for k, v in terms.items()]
        out += ["    </locale>", "  </localization>"]
    out.append("</mavlinkcamera>")
    return "\n".join(out) + "\n"


def _esc(text: str) -> str:
    return text.replace("&", "&amp;").replace("<", "&lt;").replace(">", "&gt;")


def definition_version(dialect: Dialect, model: DeviceModel, lens: str) -> int:
    """1..65535 (cam_definition_version is uint16): a CRC of the definition without its version."""
    vendor, name = _names(dialect, model, lens)
    crc = zlib.crc32(_body(vendor, name, settings_for(dialect, model, lens), 0).encode())
    return crc % 65535 + 1


def _names(dialect: Dialect, model: DeviceModel, lens: str) -> tuple[str, str]:
    vendor = dialect.title.split()[0] if dialect.title else dialect.name
    return vendor, model.name + (" thermal" if lens == "thermal" else "")


def render(dialect: Dialect, model: DeviceModel, lens: str) -> str:
    """The definition XML of one lens of one model."""
    vendor, name = _names(dialect, model, lens)
    return _body(vendor, name, settings_for(dialect, model, lens), definition_version(dialect, model, lens))


def file_name(model: DeviceModel, lens: str) -> str:
    return f"{model.name.lower()}-{lens}.xml"


def all_definitions() -> dict[str, str]:
    """{file name: XML} for every lens of every model (the checked-in contrib/camera-definitions)."""
    from ..protocol.dialects import all_models, get_model

    out: dict[str, str] = {}
    for name in all_models():
        dialect, model = get_model(name)
        for lens in ("visible", "thermal"):
            if lens == "visible" or model.thermal:
                out[file_name(model, lens)] = render(dialect, model, lens)
    return out
