"""The generated Wireshark dissector, run by tshark, against the Python decoder: every form of
every command in the catalog, plus thousands of mutated frames that probe each codec's edges."""

from __future__ import annotations

import random
from pathlib import Path

import pytest

from topgimbal.protocol import DIALECT_NAMES, get_dialect, get_model
from topgimbal.wire import CaptureWriter
from topgimbal.wire.dissector import catalog_tables

from .forms import ANY_PORT, FormFrame, device_port, expected, form_frames, mismatches
from .tshark import top_layers

pytestmark = pytest.mark.external


@pytest.fixture(scope="module")
def every_form() -> list[FormFrame]:
    return [f for name in DIALECT_NAMES for f in form_frames(get_dialect(name))]


def _compare(dissector: Path, capture: Path, cases: list[FormFrame], *args: str) -> None:
    with CaptureWriter(capture) as w:
        for i, f in enumerate(cases):
            w.udp(f.src, f.dst, f.frame.to_bytes(), ts=1_700_000_000 + i * 0.001)
    packets = top_layers(dissector, capture, *args)
    assert len(packets) == len(cases)
    problems = []
    for f, frames in zip(cases, packets, strict=True):
        assert len(frames) == 1, f.frame
        bad = mismatches(frames[0], f.expected)
        if bad:
            problems.append(f"{f.dialect} {f.frame.text()} ({f.src[1]}->{f.dst[1]}): {'; '.join(bad)}")
    assert not problems, "\n".join(problems[:40])


def test_every_form_of_the_catalog_decodes_as_in_python(every_form, dissector, tmp_path):
    _compare(dissector, tmp_path / "forms.pcap", every_form)
    # every form was exercised, each decoded by its own dialect
    built = {(f.dialect, f.ident, f.form_index) for f in every_form}
    total = {
        (n, c.ident, i) for n in DIALECT_NAMES for c in get_dialect(n).commands.values() for i in range(len(c.forms))
    }
    assert built == total
    assert all(f.expected["dialect"] == f.dialect and f.expected["fields"] is not None for f in every_form)


def test_every_form_on_the_other_dialects_port_and_on_any_port(dissector, tmp_path):
    """Where the port names the wrong dialect, a frame it cannot decode is decoded by the other
    one (the tree says which, and which was tried first); on an undocumented port the frame alone
    decides, as `decode_any` ranks the dialects."""
    other = {a: b for a, b in zip(DIALECT_NAMES, reversed(DIALECT_NAMES), strict=True)}
    cases = [f for n in DIALECT_NAMES for f in form_frames(get_dialect(n), device_port(other[n]))]
    cases += [f for n in DIALECT_NAMES for f in form_frames(get_dialect(n), ANY_PORT[1])]
    _compare(dissector, tmp_path / "crossed.pcap", cases)
    fell_back = [f for f in cases if f.expected["tried"]]
    assert len(fell_back) > 100  # the fallback was exercised, in both directions
    assert {f.expected["dialect"] for f in fell_back} == set(DIALECT_NAMES)


@pytest.mark.parametrize("model", [m["name"] for m in catalog_tables()["models"] if m["variant"]])
def test_model_preference_decodes_with_the_models_own_dialect(model, dissector, tmp_path):
    """A model whose firmware reads the document its own way (the C11's 0.5 deg/s rate step) is
    chosen with the Model preference; tshark then shows what `decode --model` shows."""
    own, _ = get_model(model)
    cases = []
    for f in form_frames(own):
        cases.append(FormFrame(f.dialect, f.ident, f.form_index, f.frame, f.src, f.dst, expected(f.frame, own)))
    _compare(dissector, tmp_path / "model.pcap", cases, "-o", f"top.model:{model}")
    default = get_dialect(own.name)
    assert any(expected(f.frame, default)["fields"] != f.expected["fields"] for f in cases)  # the variant matters


# Characters a mutation may put into data: hex of both cases, signs, points, hemispheres, bitrate
# prefixes, separators, control characters, a non-ASCII byte, and digits that overflow.
MUTATIONS = b"0123456789ABCDEFabcdef .-+_NSEWKkx!:/eE\x1f\x1c\t\xff"


def test_mutated_frames_decode_as_in_python(every_form, dissector, tmp_path):
    """Valid frames with one or two data characters replaced (checksum recomputed): the dissector
    and the Python decoder agree on which form fits, on each value, and on failure. A third of
    them go to an undocumented port, where the dialect is chosen from the frame."""
    rng = random.Random(20240612)
    cases: list[FormFrame] = []
    for f in every_form:
        for _ in range(3):
            data = bytearray(f.frame.data)
            if not data:
                continue
            for _ in range(rng.choice((1, 1, 2))):
                data[rng.randrange(len(data))] = rng.choice(MUTATIONS)
            frame = f.frame._replace(data=bytes(data))
            auto = rng.random() < 0.3
            src, dst = (("127.0.0.1", 41000), ANY_PORT) if auto else (f.src, f.dst)
            want = expected(frame, None if auto else f.dialect)
            cases.append(FormFrame(f.dialect, f.ident, f.form_index, frame, src, dst, want))
    _compare(dissector, tmp_path / "mutated.pcap", cases)
    assert sum(1 for c in cases if c.expected["fields"] is None) > 100  # failures were exercised too


def test_generated_file_is_lua_with_every_command(dissector: Path):
    text = dissector.read_text(encoding="utf-8")
    assert text.startswith("-- topgimbal.lua") and "GENERATED" in text
    for ident in ("GAC", "PTZ", "GIC", "SDC", "ERE"):
        assert f"{ident}={{" in text or f'["{ident}"]' in text
