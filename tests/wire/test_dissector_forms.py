"""The generated Wireshark dissector, run by tshark, against the Python decoder: every form of
every command in the catalog, plus thousands of mutated frames that probe each codec's edges."""

from __future__ import annotations

import math
import random
from pathlib import Path
from typing import Any

import pytest

from topgimbal.protocol import Frame
from topgimbal.wire import CaptureWriter
from topgimbal.wire.ports import decode_frame

from .forms import FormFrame, form_frames, form_label
from .tshark import top_layers, values


@pytest.fixture(scope="module")
def every_form() -> list[FormFrame]:
    return form_frames()


def _mismatches(node: dict[str, Any], expected: dict[str, Any], dialect: str) -> list[str]:
    """What the dissector shows differently from the Python decoder for one frame."""
    out = []
    if values(node, "top.id") != [expected["id"]]:
        out.append(f"id {values(node, 'top.id')}")
    if values(node, "top.dialect") != [dialect]:
        out.append(f"dialect {values(node, 'top.dialect')} != {dialect}")
    want_form = [expected["form"]] if expected["form"] else []
    if values(node, "top.form") != want_form:
        out.append(f"form {values(node, 'top.form')} != {want_form}")
    if expected["name"] is not None and (expected["fields"] is None) != bool(values(node, "top.fields_error")):
        out.append(f"fields error {values(node, 'top.fields_error')} vs {expected['error']!r}")
    nulls = values(node, "top.field_null")
    for name, want in (expected["fields"] or {}).items():
        got = values(node, f"top.field.{name}")
        if want is None:
            if name not in nulls:
                out.append(f"{name}: null expected, got {got}")
        elif isinstance(want, (int, float)) and not isinstance(want, bool):
            ok = len(got) == 1 and (
                (math.isnan(want) and got[0].lower() == "nan")
                or (math.isinf(want) and float(got[0]) == want)
                or abs(float(got[0]) - want) <= 1e-9 * max(1.0, abs(want))
            )
            if not ok:
                out.append(f"{name}: {want!r} != {got}")
        elif got != [want]:
            out.append(f"{name}: {want!r} != {got}")
    return out


def test_every_form_of_the_catalog_decodes_as_in_python(every_form, dissector, tmp_path):
    capture = tmp_path / "forms.pcap"
    with CaptureWriter(capture) as w:
        for i, f in enumerate(every_form):
            w.udp(f.src, f.dst, f.frame.to_bytes(), ts=1_700_000_000 + i * 0.001)
    packets = top_layers(dissector, capture)
    assert len(packets) == len(every_form)
    problems = []
    for f, frames in zip(every_form, packets, strict=True):
        assert len(frames) == 1, f.frame
        bad = _mismatches(frames[0], f.expected, f.dialect)
        if bad:
            problems.append(f"{f.dialect} {f.frame.text()}: {'; '.join(bad)}")
    assert not problems, "\n".join(problems[:40])
    # every form was exercised, and decoded as the form it was built from
    built = {(f.dialect, f.ident, f.form_index) for f in every_form}
    from topgimbal.protocol import DIALECT_NAMES, get_dialect

    total = {
        (n, c.ident, i) for n in DIALECT_NAMES for c in get_dialect(n).commands.values() for i in range(len(c.forms))
    }
    assert built == total


# Characters a mutation may put into data: hex of both cases, signs, points, hemispheres, bitrate
# prefixes, separators, control characters, a non-ASCII byte, and digits that overflow.
MUTATIONS = b"0123456789ABCDEFabcdef .-+_NSEWKkx!:/eE\x1f\x1c\t\xff"


def test_mutated_frames_decode_as_in_python(every_form, dissector, tmp_path):
    """Valid frames with one or two data characters replaced (checksum recomputed): the dissector
    and the Python decoder agree on which form fits, on each value, and on failure. A third of
    them go to an undocumented port, where the dialect is chosen from the frame."""
    rng = random.Random(20240612)
    cases: list[tuple[str, Frame, Any, Any, dict[str, Any]]] = []
    for f in every_form:
        for _ in range(3):
            data = bytearray(f.frame.data)
            if not data:
                continue
            for _ in range(rng.choice((1, 1, 2))):
                data[rng.randrange(len(data))] = rng.choice(MUTATIONS)
            frame = f.frame._replace(data=bytes(data))
            auto = rng.random() < 0.3
            dialect, msg = decode_frame(frame, None if auto else f.dialect)
            expected = msg.to_dict()
            expected["form"] = form_label(msg.form) if msg.form else None
            src, dst = (("127.0.0.1", 41000), ("127.0.0.1", 7777)) if auto else (f.src, f.dst)
            cases.append((dialect.name, frame, src, dst, expected))
    capture = tmp_path / "mutated.pcap"
    with CaptureWriter(capture) as w:
        for i, (_, frame, src, dst, _) in enumerate(cases):
            w.udp(src, dst, frame.to_bytes(), ts=1_700_000_000 + i * 0.001)
    packets = top_layers(dissector, capture)
    assert len(packets) == len(cases)
    problems = []
    for (name, frame, _, _, expected), frames in zip(cases, packets, strict=True):
        bad = _mismatches(frames[0], expected, name)
        if bad:
            problems.append(f"{name} {frame.text()}: {'; '.join(bad)}")
    assert not problems, "\n".join(problems[:40])
    assert sum(1 for c in cases if c[4]["fields"] is None) > 100  # failures were exercised too


def test_generated_file_is_lua_with_every_command(dissector: Path):
    text = dissector.read_text(encoding="utf-8")
    assert text.startswith("-- topgimbal.lua") and "GENERATED" in text
    for ident in ("GAC", "PTZ", "GIC", "SDC", "ERE"):
        assert f"{ident}={{" in text or f'["{ident}"]' in text
