"""The simulator's timerfd wake-up (sim/precise_timer.py): it calls back once per arming, never
after a cancel or for an expiry that a re-arm replaced, closes its fd, and stands aside where the
loop's clock is not CLOCK_MONOTONIC (a virtual-time loop keeps call_at). How precisely frames then
leave is a figure (bench/latency.py, attitude jitter), not an assertion here."""

from __future__ import annotations

import asyncio
import os
import sys

import pytest

from topgimbal.clock import reads_system_monotonic
from topgimbal.sim import FakeClock, Simulator, precise_timer

pytestmark = [
    pytest.mark.loopback,
    pytest.mark.skipif(not sys.platform.startswith("linux"), reason="timerfd is Linux's"),
]


async def _timer() -> tuple[precise_timer.PreciseTimer, list[float]]:
    loop = asyncio.get_running_loop()
    calls: list[float] = []
    timer = precise_timer.make(loop, lambda: calls.append(loop.time()))
    assert timer is not None, "asyncio's own loop on Linux gets a timerfd"
    return timer, calls


async def test_it_calls_back_once_at_or_after_its_time() -> None:
    timer, calls = await _timer()
    loop = asyncio.get_running_loop()
    try:
        at = loop.time() + 0.05
        timer.arm(at)
        await asyncio.sleep(0.3)
        assert len(calls) == 1
        assert calls[0] >= at  # never early: the kernel expires it at its time
        assert not timer.armed
    finally:
        timer.close()


async def test_a_cancelled_wake_up_never_comes() -> None:
    timer, calls = await _timer()
    loop = asyncio.get_running_loop()
    try:
        timer.arm(loop.time() + 0.03)
        timer.cancel()
        await asyncio.sleep(0.2)
        assert calls == []
    finally:
        timer.close()


async def test_an_expiry_replaced_by_a_new_arming_is_not_called_back() -> None:
    timer, calls = await _timer()
    loop = asyncio.get_running_loop()
    try:
        timer.arm(loop.time() - 1.0)  # expired at once: the fd is readable...
        timer.arm(loop.time() + 30.0)  # ...and re-armed before the loop has run its reader
        await asyncio.sleep(0.1)
        assert calls == []  # the first expiry is gone with its arming
        timer.arm(loop.time() + 0.01)
        await asyncio.sleep(0.2)
        assert len(calls) == 1
    finally:
        timer.close()


async def test_close_releases_the_fd() -> None:
    timer, _ = await _timer()
    fd = timer._fd
    os.fstat(fd)  # open
    timer.close()
    with pytest.raises(OSError):
        os.fstat(fd)
    timer.close()  # twice is harmless


class _OwnClockLoop(asyncio.SelectorEventLoop):
    """A loop whose time is its own (as a virtual-time test loop's is)."""

    def time(self) -> float:
        return 1000.0


def test_a_loop_with_a_clock_of_its_own_keeps_call_at() -> None:
    loop = _OwnClockLoop()
    try:
        assert not reads_system_monotonic(loop)
        assert precise_timer.make(loop, lambda: None) is None
    finally:
        loop.close()


async def test_the_simulator_streams_on_it_and_lets_it_go() -> None:
    sim = Simulator("C12")
    await sim.start(udp=[("127.0.0.1", 0)])
    try:
        assert sim._precise is not None
        assert sim._early_s == precise_timer.PRECISE_EARLY_S
    finally:
        await sim.stop()
    assert sim._precise is None
    fake = Simulator("C12", clock=FakeClock())
    await fake.start(udp=[])
    try:
        assert fake._precise is None  # virtual time: sim.advance() drives it
    finally:
        await fake.stop()
