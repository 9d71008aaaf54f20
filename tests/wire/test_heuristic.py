"""One rule takes traffic on an undocumented port for TOP (issue 27): `decode --pcap` and the
Wireshark dissector's heuristic both come from wire/heuristic.py. Before, the Lua wanted two
address letters after the header and the Python only the header (1 packet in 2,441 mutated ones
differed), and the Lua looked at 16 bytes only (more line ends before the header: TOP for one).
Checked on mutated payloads: the Lua function under Lua 5.2/5.3/5.4 (lupa), and tshark itself
against `frames_in_capture` on a capture of them."""

from __future__ import annotations

import importlib
import random
from pathlib import Path
from typing import Any

import pytest

from topgimbal.wire import CaptureWriter
from topgimbal.wire.capture import WireFrame, frames_in_capture
from topgimbal.wire.dissector import core_source, generated_tables
from topgimbal.wire.heuristic import MAX_LEADING_LINE_ENDS, looks_like_top

from .test_dissector_wire import _mutate, _pool
from .tshark import top_layers

pytestmark = pytest.mark.external

OTHER_PORT = 7777  # documented for no dialect: only the heuristic takes it


def _mutated(rng: random.Random) -> bytes:
    """A payload near a TOP frame's start: line ends first, a changed or cut header or address."""
    p = _mutate(rng, rng.choice(_pool()))
    kind = rng.randrange(6)
    if kind == 0:
        p = (
            b"".join(rng.choice([b"\r", b"\n", b"\r\n"]) for _ in range(rng.randrange(0, 2 * MAX_LEADING_LINE_ENDS)))
            + p
        )
    elif kind == 1:
        i = rng.randrange(0, 6)
        p = p[:i] + bytes([rng.choice(b"#TPtpUMDEPGXZ0\r\n \x00\xff")]) + p[i + 1 :]
    elif kind == 2:
        p = p[: rng.randrange(1, 7)]
    elif kind == 3:
        p = b"\r\n" * rng.randrange(0, 3) + p[: rng.randrange(1, 8)]
    return p or b"\n"


@pytest.mark.parametrize("version", ["lua52", "lua53", "lua54"])
def test_the_lua_heuristic_is_the_python_rule(version: str) -> None:
    lua = importlib.import_module(f"lupa.{version}").LuaRuntime(encoding=None, unpack_returned_tuples=True)
    core = lua.execute(generated_tables().encode() + core_source().encode() + b"\nreturn CORE")
    rng = random.Random(27)
    payloads = [_mutated(rng) for _ in range(5000)]
    payloads += [b"\r\n" * n + b"#TPUG2wPTZ006A" for n in range(12)]  # the line-end limit, both sides
    payloads += [b"#TP", b"#TPU", b"#TPX", b"#TPUX", b"#tpDU", b"#Tp\r\n", b"\n#tP"]
    differ = [p for p in payloads if bool(core.looks_like_top(p)) != looks_like_top(p)]
    assert differ == []
    taken = sum(looks_like_top(p) for p in payloads)
    assert 500 < taken < len(payloads) - 500  # the mutations exercise both answers


def test_rule_examples() -> None:
    assert looks_like_top(b"#TPUG2wPTZ006A")
    assert looks_like_top(b"\r\n#tpDU3rVER0105025A")
    assert looks_like_top(b"#TP")  # a TCP segment that ends after the header
    assert looks_like_top(b"#TPU")
    assert not looks_like_top(b"#TPX")  # not an address letter
    assert not looks_like_top(b"#TPUX")
    assert not looks_like_top(b"#TX")
    assert not looks_like_top(b"\r\n" * MAX_LEADING_LINE_ENDS + b"#TPUG")
    assert looks_like_top(b"\n" * MAX_LEADING_LINE_ENDS + b"#TPUG")


def test_tshark_and_decode_pcap_take_the_same_packets(dissector: Path, tmp_path: Path) -> None:
    rng = random.Random(2441)
    payloads = [_mutated(rng) for _ in range(400)]
    payloads += [b"#TPXX" + b"#TPUG2wPTZ006A", b"\r\n" * 9 + b"#TPUG2wPTZ006A"]  # the cases that differed
    capture = tmp_path / "mutated.pcap"
    with CaptureWriter(capture) as w:
        for i, p in enumerate(payloads):
            # each packet its own conversation: the heuristic decides for each
            w.udp(("127.0.0.1", 20000 + i), ("127.0.0.1", OTHER_PORT), p, ts=1_700_000_000 + i * 0.01)
    tshark_numbers = {n for n, s in enumerate(_numbers_shown(dissector, capture), 1) if s}
    python_numbers = {item.number for item in frames_in_capture(capture) if isinstance(item, WireFrame)}
    assert tshark_numbers == python_numbers
    assert 50 < len(python_numbers) < len(payloads) - 50


def _numbers_shown(dissector: Path, capture: Path) -> list[bool]:
    """Per packet of the capture, whether the dissector showed TOP in it."""
    layers: list[Any] = top_layers(dissector, capture)
    return [bool(frames) for frames in layers]
