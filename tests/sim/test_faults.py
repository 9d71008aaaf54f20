"""Every fault kind, on the pure injector (fake times) and through a real UDP socket."""

from __future__ import annotations

import json
import random
from pathlib import Path

import pytest

from topgimbal.protocol import Frame, FrameParser
from topgimbal.sim import FakeClock, FaultInjector, FaultPlan, FaultPlanError, Simulator

from .conftest import LOOP, UdpClient, req

pytestmark = pytest.mark.loopback

PKT = b"#TPGU2wPTZ0067"


def inj(**kw: object) -> FaultInjector:
    return FaultInjector(FaultPlan(**kw), "out", random.Random(7), 0.0)  # type: ignore[arg-type]


def run(i: FaultInjector, n: int = 1000, reply: bool = False) -> list[bytes]:
    out = []
    for k in range(n):
        out += [d for _, d in i.submit("p", PKT, k * 0.01, reply=reply)]
    out += [d for _, d in i.due(1e9)]
    return out


def test_drop_fraction_close_to_plan() -> None:
    n = len(run(inj(drop=0.3)))
    assert 640 < n < 760


def test_duplicate() -> None:
    n = len(run(inj(duplicate=0.2)))
    assert 1150 < n < 1250


def test_corrupt_flips_exactly_one_bit_and_parser_drops_it() -> None:
    out = run(inj(corrupt=1.0), n=50)
    assert len(out) == 50
    for d in out:
        diff = [a ^ b for a, b in zip(d, PKT, strict=True)]
        assert sum(bin(x).count("1") for x in diff) == 1
    good = sum(1 for d in out if any(isinstance(x, Frame) for x in FrameParser().feed_datagram(d)))
    assert good < 10  # nearly every flip breaks the checksum, the header or an address


def test_truncate_shortens() -> None:
    out = run(inj(truncate=1.0), n=50)
    assert all(0 < len(d) < len(PKT) for d in out)


def test_delay_and_jitter() -> None:
    i = inj(delay_s=0.1, jitter_s=0.05)
    assert i.submit("p", PKT, 0.0) == []
    assert i.due(0.099) == []
    assert [d for _, d in i.due(0.151)] == [PKT]


def test_reorder_swaps_with_the_next_packet_or_releases_after_hold() -> None:
    i = inj(reorder=1.0, reorder_hold_s=0.2)
    assert i.submit("p", b"first", 0.0) == []
    assert [d for _, d in i.submit("p", b"second", 0.01)] == [b"second", b"first"]
    i2 = inj(reorder=1.0, reorder_hold_s=0.2)
    assert i2.submit("p", b"alone", 0.0) == []
    assert i2.due(0.1) == [] and [d for _, d in i2.due(0.2)] == [b"alone"]


def test_silence_windows_relative_to_start() -> None:
    i = FaultInjector(FaultPlan(silence=((1.0, 2.0),)), "out", random.Random(1), 100.0)
    assert i.submit("p", PKT, 100.5) != []
    assert i.submit("p", PKT, 101.5) == []
    assert i.submit("p", PKT, 102.0) != []


def test_late_reply_only_for_replies() -> None:
    i = inj(late_reply_s=0.5)
    assert i.submit("p", PKT, 0.0, reply=False) != []  # a stream frame is not late
    assert i.submit("p", PKT, 0.0, reply=True) == []
    assert [d for _, d in i.due(0.5)] == [PKT]


def test_direction_limits_where_faults_apply() -> None:
    plan = FaultPlan(drop=1.0, direction="in")
    assert FaultInjector(plan, "out", random.Random(0), 0).submit("p", PKT, 0) != []
    assert FaultInjector(plan, "in", random.Random(0), 0).submit("p", PKT, 0) == []


def test_same_seed_same_damage() -> None:
    a = run(FaultInjector(FaultPlan(drop=0.2, corrupt=0.2, duplicate=0.1), "out", random.Random(3), 0))
    b = run(FaultInjector(FaultPlan(drop=0.2, corrupt=0.2, duplicate=0.1), "out", random.Random(3), 0))
    assert a == b


def test_parse_text_and_json_forms(tmp_path: Path) -> None:
    p = FaultPlan.parse("drop=0.3, corrupt=10%, delay_s=0.05, silence=2-3;5-6.5, direction=out")
    assert (p.drop, p.corrupt, p.delay_s, p.direction) == (0.3, 0.1, 0.05, "out")
    assert p.silence == ((2.0, 3.0), (5.0, 6.5))
    f = tmp_path / "plan.json"
    f.write_text(json.dumps(p.to_dict()))
    assert FaultPlan.parse(str(f)) == p
    assert FaultPlan.parse("@" + str(f)) == p


@pytest.mark.parametrize(
    ("text", "message"),
    [
        ("drop=1.5", "drop=1.5: expected a probability 0..1"),
        ("loss=0.1", "unknown fault 'loss'; allowed: drop, duplicate"),
        ("drop", "expected KEY=VALUE"),
        ("delay_s=abc", "delay_s='abc': expected a number"),
        ("silence=3-2", "expected 0 <= start_s < end_s"),
        ("silence=3", "expected START-END"),
        ("direction=sideways", "expected one of both, in, out"),
    ],
)
def test_parse_errors_name_the_problem(text: str, message: str) -> None:
    with pytest.raises(FaultPlanError, match=message.replace("(", r"\(").replace(".", r"\.")):
        FaultPlan.parse(text)


async def test_faults_on_a_real_udp_socket_with_a_fake_clock() -> None:
    clock = FakeClock()
    plan = FaultPlan(delay_s=0.2, duplicate=1.0, direction="out")
    async with Simulator("C12", clock=clock, faults=plan, listen={"udp": [(LOOP, 0)]}) as sim:
        c = UdpClient(sim.addresses["udp"][0])
        try:
            assert await c.request(req("C12", "REC", read=True), wait=0.2) == []  # held 0.2 s (fake)
            sim.advance(0.2)
            got = await c.collect(wait=0.5, count=2)
            assert [f.ident for f in got] == ["REC", "REC"]
            assert sim.fault_counts["out"]["duplicate"] == 1
        finally:
            c.close()


async def test_inbound_drop_means_no_answer_and_nothing_received() -> None:
    async with Simulator("C12", faults=FaultPlan(drop=1.0, direction="in"), listen={"udp": [(LOOP, 0)]}) as sim:
        c = UdpClient(sim.addresses["udp"][0])
        try:
            assert await c.request(req("C12", "REC", read=True), wait=0.2) == []
            assert sim.received == []
        finally:
            c.close()
