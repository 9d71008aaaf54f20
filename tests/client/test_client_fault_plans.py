"""End to end under the simulator's fault plans (issue 15): write-then-read of a setting from two
concurrent workers plus photos, every outcome checked against what the simulated device itself
held at the time. Bounded: a fixed number of rounds, each plan under a wait_for."""

from __future__ import annotations

import asyncio
import itertools

import pytest

import topgimbal
from topgimbal.clock import monotonic
from topgimbal.errors import TopGimbalError
from topgimbal.sim import FaultPlan, Simulator

pytestmark = [pytest.mark.loopback, pytest.mark.integration]

PLANS = {
    # the first finding: answers later than the timeout were taken by the next read
    "late": FaultPlan(late_reply_s=0.4, late_reply_p=0.5, direction="out"),
    "drop": FaultPlan(drop=0.3),
    "everything": FaultPlan(
        drop=0.1, duplicate=0.1, corrupt=0.1, truncate=0.05, reorder=0.1, delay_s=0.02, jitter_s=0.1,
        late_reply_s=0.4, late_reply_p=0.2,
    ),
}  # fmt: skip
ROUNDS = {"late": 8, "drop": 4, "everything": 4}
_names = itertools.count()

# Every plan on memory:// in virtual time (looptime: the timeouts, late replies and delays take no
# real time), and one real-time smoke over loopback UDP that proves the same with real sockets.
CASES = [
    *(pytest.param(plan, "memory", marks=[pytest.mark.looptime, pytest.mark.virtual], id=plan) for plan in PLANS),
    pytest.param("everything", "udp", id="everything-udp-real-time"),
]


@pytest.mark.parametrize(("plan", "transport"), CASES)
async def test_no_wrong_answer_under_a_fault_plan(sim_factory, plan, transport):
    if transport == "memory":
        sim = await Simulator(model="C12", seed=51, faults=PLANS[plan]).start(udp=[])
        url = sim.listen_memory(f"fault-plan-{next(_names)}")
    else:
        sim = await sim_factory("C12", seed=51, faults=PLANS[plan])
        url = dict(sim.endpoints)["udp"]
    held: list[tuple[float, str, int]] = []  # (since, ip, tas) after every frame the device handled
    original = sim.device.handle

    def handle(peer, frame):
        out = original(peer, frame)
        now = (sim.network.ip, sim.settings["TAS"]["interval_s"])
        if not held or held[-1][1:] != now:
            held.append((monotonic(), *now))
        return out

    sim.device.handle = handle
    held.append((monotonic(), sim.network.ip, sim.settings["TAS"]["interval_s"]))
    outcomes = {"ok": 0, "failed": 0}
    photos_acked = 0

    def values_between(column: int, a: float, b: float) -> set:
        out = {row[column] for row in held if a <= row[0] <= b}
        before = [row[column] for row in held if row[0] < a]
        return out | ({before[-1]} if before else set())

    async def worker(cam, ident: str, field: str, column: int, values) -> None:
        for v in itertools.islice(values, ROUNDS[plan]):
            for read in (False, True):
                start = monotonic()
                try:
                    m = await (cam.request(ident, read=True) if read else cam.request(ident, **{field: v}))
                except TopGimbalError:
                    outcomes["failed"] += 1
                    continue
                got = m.fields[field] if read else v
                assert got in values_between(column, start, monotonic()), (plan, ident, read, got)
                outcomes["ok"] += 1

    async def photographer(cam) -> None:
        nonlocal photos_acked
        for _ in range(4):
            try:
                await cam.photo()
                photos_acked += 1
            except TopGimbalError as exc:
                assert "may or may not have been taken" in str(exc) or "link" in str(exc)

    async def body() -> None:
        async with topgimbal.connect(url, model="C12", timeout_s=0.3, retries=2, dup_window_s=0.25) as cam:
            before = sim.camera.photos_taken
            ips = (f"10.1.{i}.{i + 1}" for i in itertools.count(1))
            await asyncio.gather(
                worker(cam, "IPV", "address", 1, ips),
                worker(cam, "TAS", "interval_s", 2, itertools.cycle(range(3, 26, 4))),
                photographer(cam),
            )
            assert sim.camera.photos_taken - before >= photos_acked
            sent = sum(1 for f in sim.received if f.ident == "CAP")
            assert sent <= 4 * (2 if PLANS[plan].duplicate else 1)  # never retried

    try:
        await asyncio.wait_for(body(), 120)
    finally:
        if transport == "memory":
            await sim.stop()
    assert outcomes["ok"] >= 8, outcomes
