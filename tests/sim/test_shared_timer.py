"""sim/shared_timer.py: one loop timer for many simulators (`sim --fleet`). Wake-ups run in time
order, coincident ones in one fire, a cancelled one never; one callback's failure is not the
others'; a callback that asks for "now" again waits for the next fire; cancelled entries do not
pile up. And simulators that share one stream as they do on timers of their own."""

from __future__ import annotations

import asyncio
import logging

import pytest

from topgimbal.client.aio import AsyncClient
from topgimbal.sim.shared_timer import COMPACT_SLACK, SharedTimer
from topgimbal.sim.simulator import Simulator

pytestmark = pytest.mark.virtual


async def test_wake_ups_run_in_time_order_and_coincident_ones_in_one_fire() -> None:
    timer = SharedTimer()
    t0 = timer.time()
    ran: list[str] = []
    for name, dt in (("late", 0.020), ("a", 0.010), ("early", 0.005), ("b", 0.010)):
        timer.call_at(t0 + dt, lambda name=name: ran.append(name))
    gone = timer.call_at(t0 + 0.015, lambda: ran.append("cancelled"))
    gone.cancel()
    gone.cancel()  # twice: still one live entry fewer
    assert len(timer) == 4
    await asyncio.sleep(0.05)
    assert ran == ["early", "a", "b", "late"]
    assert (timer.fired, timer.ran, len(timer)) == (3, 4, 0)  # a and b: one fire


async def test_a_failing_callback_does_not_stop_the_others(caplog: pytest.LogCaptureFixture) -> None:
    timer = SharedTimer()
    t0 = timer.time()
    ran: list[int] = []

    def boom() -> None:
        raise ValueError("a simulator's bug")

    timer.call_at(t0 + 0.01, boom)
    timer.call_at(t0 + 0.01, lambda: ran.append(1))
    with caplog.at_level(logging.ERROR, logger="topgimbal.sim"):
        await asyncio.sleep(0.02)
    assert ran == [1]
    assert "timer callback failed" in caplog.text and "a simulator's bug" in caplog.text


async def test_a_callback_asking_for_now_again_waits_for_the_next_fire() -> None:
    timer = SharedTimer()
    runs: list[int] = []

    def again() -> None:
        runs.append(timer.fired)
        if len(runs) < 50:
            timer.call_at(timer.time(), again)

    timer.call_at(timer.time(), again)
    await asyncio.sleep(0.01)
    assert len(runs) == 50
    assert runs == sorted(set(runs))  # each in a fire of its own: no fire ran two of them


async def test_cancelled_entries_do_not_pile_up() -> None:
    timer = SharedTimer()
    far = timer.time() + 100.0
    for _ in range(20):
        entries = [timer.call_at(far, lambda: None) for _ in range(500)]
        for e in entries:
            e.cancel()
        assert len(timer._heap) <= 2 * 500 + COMPACT_SLACK + 1  # bounded by the live ones at each push
    assert len(timer) == 0
    timer.call_at(far, lambda: None)  # the next push drops the dead ones
    assert len(timer) == 1 and len(timer._heap) == 1
    timer.close()
    assert len(timer._heap) == 0


async def test_simulators_on_one_shared_timer_stream_as_on_their_own() -> None:
    timer = SharedTimer()
    sims = [Simulator("C12", seed=i, timer=timer) for i in range(3)]
    own = Simulator("C12", seed=9)  # on a timer of its own, beside them
    clients = []
    try:
        for i, sim in enumerate([*sims, own]):
            await sim.start(udp=[])
            client = AsyncClient(sim.listen_memory(f"shared-timer-{i}"), "C12")
            await client.open()
            await client.attitude_stream(50)
            clients.append(client)
        got = [0] * len(clients)
        taps = [c.streams.tap(lambda att, i=i: got.__setitem__(i, got[i] + 1)) for i, c in enumerate(clients)]
        await asyncio.sleep(2.0)
        for remove in taps:
            remove()
        assert all(95 <= n <= 105 for n in got), got  # 50 Hz for 2 s, each of them
        assert timer.ran >= 3 * 95 and timer.fired <= timer.ran
    finally:
        for c in clients:
            await c.close()
        for sim in [*sims, own]:
            await sim.stop()
        timer.close()
