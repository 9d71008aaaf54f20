"""The dissector's Lua under every Lua a Wireshark embeds: 5.2 (Wireshark up to 4.2; Debian's
tshark 4.0 here) and 5.3 / 5.4 (Wireshark 4.4 and later), run in-process by lupa (which bundles
the reference interpreters of each version).

- The pure core (codec decoders, frame scanner) against the Python codecs and FrameParser.
- The whole generated file, Wireshark glue included, over a small shim of Wireshark's API
  (`wireshark_shim.lua`): every form of the catalog decodes as the Python decoder says, and the
  tree and the Info column are the same text under every version (tshark itself is compared with
  Python in test_dissector_forms, so the three versions show what Wireshark 4.0 shows).
"""

from __future__ import annotations

import importlib
import random
from datetime import datetime
from pathlib import Path
from typing import Any

import pytest

from topgimbal.protocol import DIALECT_NAMES, FrameParser, get_dialect
from topgimbal.protocol.examples import example_values
from topgimbal.protocol.fields import Codec
from topgimbal.wire.dissector import (
    catalog_tables,
    codec_entry,
    core_source,
    generate_dissector,
    generated_tables,
    to_lua,
)

from .forms import ANY_PORT, FormFrame, expected, form_frames, mismatches
from .test_dissector_wire import _lua_items, _mutate, _pool, _python_items

pytestmark = pytest.mark.external

VERSIONS = ["lua52", "lua53", "lua54"]
SHIM = (Path(__file__).with_name("wireshark_shim.lua")).read_bytes()
# data characters a mutation may use: every codec's edges (see test_dissector_forms.MUTATIONS)
MUTATIONS = b"0123456789ABCDEFabcdef .-+_NSEWKkx!:/eE\x1f\x1c\t\xff"


def _lua(version: str) -> Any:
    return importlib.import_module(f"lupa.{version}")  # lupa is a dev dependency (pyproject.toml)


def _runtime(version: str) -> Any:
    return _lua(version).LuaRuntime(encoding=None, unpack_returned_tuples=True)


def _first(result: Any) -> Any:
    return result[0] if isinstance(result, tuple) else result


def _to_py(mod: Any, obj: Any) -> Any:
    """Lua tables as dicts (1..n as lists); strings as text."""
    if isinstance(obj, bytes):
        return obj.decode("utf-8")
    if mod.lua_type(obj) != "table":
        return obj
    keys = list(obj.keys())
    if keys and keys == list(range(1, len(keys) + 1)):
        return [_to_py(mod, obj[k]) for k in keys]
    return {(k.decode() if isinstance(k, bytes) else k): _to_py(mod, v) for k, v in obj.items()}


# -- the core: codecs ------------------------------------------------------------------------------


def _codecs() -> list[tuple[int, Codec]]:
    """(index in GEN.codecs, a Python codec with that entry) for every codec of the catalog."""
    index = {to_lua(entry): i for i, entry in enumerate(catalog_tables()["codecs"], 1)}
    out: dict[int, Codec] = {}
    for name in DIALECT_NAMES:
        for spec in get_dialect(name).commands.values():
            for form in spec.forms:
                for f in form.fields:
                    out.setdefault(index[to_lua(codec_entry(f.codec, f.name))], f.codec)
    return sorted(out.items())


def _raw_inputs(codec: Codec, rng: random.Random) -> list[bytes]:
    good = []
    for v in example_values(codec):
        try:
            good.append(codec.encode(v))
        except ValueError:
            continue
    out = list(good)
    for raw in good:
        for _ in range(6):
            b = bytearray(raw) or bytearray(b"0")
            for _ in range(rng.choice((1, 1, 2))):
                b[rng.randrange(len(b))] = rng.choice(MUTATIONS)
            out.append(bytes(b))
        out.append(raw[:-1])
        out.append(raw + raw[-1:])
    return out


def _python_shown(value: Any) -> str:
    """What the dissector must print for a decoded value: Python's own str()."""
    if value is None:
        return "null"
    if isinstance(value, datetime):
        return value.isoformat()
    return str(value)


@pytest.mark.parametrize("version", VERSIONS)
def test_codec_decoders_equal_the_python_codecs(version):
    """Every codec of the catalog, on valid and mutated data: the same value or the same refusal,
    and the value printed exactly as Python prints it (integers without a point, floats as repr)."""
    mod = _lua(version)
    core, gen = _runtime(version).execute(generated_tables().encode() + core_source().encode() + b"\nreturn CORE, GEN")
    rng = random.Random(7)
    checked = refused = 0
    problems = []
    for index, codec in _codecs():
        c = gen.codecs[index]
        for raw in _raw_inputs(codec, rng):
            try:
                want: Any = codec.decode(raw)
                ok = True
            except ValueError:
                ok = False
            got = _first(core.DECODE[c.k](c, raw))
            if not ok:
                refused += 1
                if got is not None:
                    problems.append(f"{codec!r} {raw!r}: Python refuses, Lua gives {got!r}")
                continue
            checked += 1
            if got is None:
                problems.append(f"{codec!r} {raw!r}: Python gives {want!r}, Lua refuses")
                continue
            shown = _to_py(mod, core.show(got, c))
            if shown != _python_shown(want):
                problems.append(f"{codec!r} {raw!r}: Python {_python_shown(want)!r}, Lua {shown!r}")
    assert not problems, "\n".join(problems[:30])
    assert checked > 500 and refused > 300


# -- the core: the frame scanner -------------------------------------------------------------------


@pytest.mark.parametrize("version", VERSIONS)
def test_scanner_finds_the_frames_the_parser_finds(version):
    core = _runtime(version).execute(generated_tables().encode() + core_source().encode() + b"\nreturn CORE")
    rng = random.Random(11)
    pool = _pool()
    found = 0
    for _ in range(300):
        datagram = b"".join(_mutate(rng, rng.choice(pool)) for _ in range(rng.randrange(1, 5)))
        lua = []
        for it in _first(core.items_in(datagram, False)).values():
            a, b = int(it.a), int(it.b)
            if it.kind in (b"frame", b"bad_checksum"):
                data = datagram[a + 10 : b - 2]
                shown = "".join(chr(x) if 0x20 <= x < 0x7F else f"\\x{x:02x}" for x in data)
                lua.append(
                    ("frame", core.split_frame(datagram, it).ident.decode(), shown, "1" if it.kind == b"frame" else "0")
                )
            else:
                lua.append(("skip", datagram[a:b].hex()))
        assert lua == _python_items(FrameParser().feed_datagram(datagram)), datagram
        found += sum(1 for x in lua if x[0] == "frame")
    assert found > 300


# -- the whole file over a Wireshark shim ----------------------------------------------------------


def _dissector(version: str) -> tuple[Any, Any]:
    lua = _runtime(version)
    lua.execute(SHIM)
    lua.execute(generate_dissector().encode())
    return lua, lua.globals().SHIM


def _flatten(mod: Any, node: Any, payload: bytes, out: dict[str, Any], texts: list[str]) -> None:
    """A TOP subtree as tshark's JSON shows it (abbreviation -> value text), and every item's text."""
    for child in node.children.values():
        abbr = child.abbr.decode()
        value = child.value
        if value is None and abbr == "top.garbage":
            value = ":".join(f"{b:02x}" for b in payload[child.range_off : child.range_off + child.range_len])
        elif isinstance(value, bytes):
            value = value.decode("utf-8")
        elif isinstance(value, (int, float)) and not isinstance(value, bool):
            value = repr(float(value)) if abbr.startswith("top.field.") else str(int(value))
        if value is not None:
            out.setdefault(abbr, []).append(value)
        label = child.label.decode("utf-8") if child.label is not None else ""
        texts.append(f"{abbr} {label} {[e.abbr.decode() for e in child.experts.values()]}")
        _flatten(mod, child, payload, out, texts)


def _run(version: str, cases: list[FormFrame], prefs: dict[str, int] | None = None) -> list[Any]:
    mod = _lua(version)
    _, shim = _dissector(version)
    for k, v in (prefs or {}).items():
        shim.protos[b"top"].prefs[k.encode()] = v
    out = []
    for f in cases:
        payload = f.frame.to_bytes()
        root, cols = shim.dissect(payload, f.src[1], f.dst[1])
        frames = []
        texts: list[str] = []
        for sub in root.children.values():
            flat: dict[str, Any] = {}
            _flatten(mod, sub, payload, flat, texts)
            frames.append(flat)
        out.append((frames, texts, cols.info.decode("utf-8") if cols.info else ""))
    return out


@pytest.fixture(scope="module")
def cases() -> list[FormFrame]:
    forms = [f for n in DIALECT_NAMES for f in form_frames(get_dialect(n))]
    forms += [f for n in DIALECT_NAMES for f in form_frames(get_dialect(n), ANY_PORT[1])]
    rng = random.Random(5)
    for f in list(forms[: len(forms) // 2]):
        data = bytearray(f.frame.data)
        if data:
            data[rng.randrange(len(data))] = rng.choice(MUTATIONS)
            frame = f.frame._replace(data=bytes(data))
            forms.append(FormFrame(f.dialect, f.ident, f.form_index, frame, f.src, f.dst, expected(frame, f.dialect)))
    return forms


def test_the_dissector_shows_the_same_under_every_lua(cases):
    runs = {v: _run(v, cases) for v in VERSIONS}
    problems = []
    for f, (frames, _, _) in zip(cases, runs["lua54"], strict=True):
        assert len(frames) == 1, f.frame
        bad = mismatches(frames[0], f.expected)
        if bad:
            problems.append(f"{f.frame.text()}: {'; '.join(bad)}")
    assert not problems, "\n".join(problems[:30])
    for v in ("lua52", "lua53"):
        for f, mine, ref in zip(cases, runs[v], runs["lua54"], strict=True):
            assert mine[1:] == ref[1:], f"{v} and lua54 differ on {f.frame.text()}"


@pytest.mark.parametrize("version", VERSIONS)
def test_wire_behaviour_under_every_lua(version):
    """Several frames, garbage and a bad checksum in one datagram; the Info column; the heuristic
    on an undocumented port; the Model preference."""
    _, shim = _dissector(version)
    mod = _lua(version)
    rng = random.Random(3)
    pool = _pool()
    for _ in range(60):
        datagram = b"".join(_mutate(rng, rng.choice(pool)) for _ in range(rng.randrange(1, 4)))
        root, _ = shim.dissect(datagram, 40000, 5000)
        frames = []
        for sub in root.children.values():
            flat: dict[str, Any] = {}
            _flatten(mod, sub, datagram, flat, [])
            frames.append(flat)
        assert _lua_items(frames) == [x for x in _python_items(FrameParser().feed_datagram(datagram))]
    gac = b"#tpGUCrGACFF36ED5A0048E3"
    _, cols = shim.dissect(gac, 7777, 40000)
    assert cols.info == b"GAC attitude yaw=-2.02 pitch=-47.74 roll=0.72"
    c11 = next(i for i, m in enumerate(catalog_tables()["models"], 1) if m["name"] == "C11")
    gsy = b"#TPUG2wGSY14" + b"%02X" % (sum(b"#TPUG2wGSY14") % 256)
    assert shim.dissect(gsy, 40000, 5000)[1].info == b"GSY yaw_rate yaw_rate=2.0"
    shim.protos[b"top"].prefs[b"model"] = c11
    assert shim.dissect(gsy, 40000, 5000)[1].info == b"GSY yaw_rate yaw_rate=10.0"
