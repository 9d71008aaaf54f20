"""The serving process's one task for every camera's periodic checks (fleet/ticker.py): every
camera polled each tick, the calls check every `gone_s`, a camera that raises logged without
stopping the others, a removed camera no longer polled."""

from __future__ import annotations

import asyncio
import logging

import pytest

from topgimbal.fleet.ticker import SLICE, CameraTicker

from .conftest import eventually

pytestmark = pytest.mark.virtual


class Cam:
    def __init__(self, name: str, broken: bool = False) -> None:
        self.name, self.broken = name, broken
        self.states = 0
        self.gones = 0

    def poll_state(self) -> None:
        self.states += 1
        if self.broken:
            raise RuntimeError("a bug in one camera")

    def poll_gone(self) -> None:
        self.gones += 1


async def test_every_camera_is_polled_and_one_that_raises_stops_nobody(caplog: pytest.LogCaptureFixture) -> None:
    ticker = CameraTicker(0.01, 0.02)
    cams = [Cam("north"), Cam("east", broken=True), Cam("south")]
    removes = [ticker.add(c) for c in cams]
    try:
        with caplog.at_level(logging.ERROR, logger="topgimbal.fleet"):
            await eventually(lambda: all(c.states >= 6 for c in cams), 10, "6 ticks for every camera")
        assert "east: a periodic check failed" in caplog.text
        assert caplog.text.count("a periodic check failed") == 1  # then at most every LOG_EVERY_S
        assert ticker.failures >= 6
        north, south = cams[0], cams[2]
        # the calls check every second tick (0.02 s at 0.01 s a tick); the broken one raised before it
        assert north.gones in (north.states // 2, north.states // 2 - 1, north.states // 2 + 1)
        assert cams[1].gones == 0
        removes[0]()
        seen = north.states
        await eventually(lambda: south.states >= seen + 3, 10, "3 more ticks")
        assert north.states == seen  # removed: no longer polled
    finally:
        await ticker.close()
    after = south.states
    await asyncio.sleep(0.05)
    assert south.states == after  # closed: nothing runs


def test_periods_out_of_order_are_refused() -> None:
    with pytest.raises(ValueError, match="state_s"):
        CameraTicker(0.5, 0.25)
    with pytest.raises(ValueError, match="state_s"):
        CameraTicker(0.0, 0.5)


async def test_a_tick_lets_the_loop_run_between_slices_and_skips_a_camera_removed_meanwhile() -> None:
    """1,000 cameras' checks in one callback held the serving loop for milliseconds: a tick runs
    SLICE of them at a time, and what else is ready (a socket read) runs in between. Here the
    first camera's check makes such work ready; that work closes the last camera."""
    ticker = CameraTicker(0.01, 0.02)
    order: list[str] = []

    def other_work() -> None:
        order.append("other")
        removes[-1]()

    class Logged(Cam):
        def poll_state(self) -> None:
            super().poll_state()
            order.append(self.name)
            if self is cams[0] and self.states == 1:
                asyncio.get_running_loop().call_soon(other_work)

    cams = [Logged(f"cam{i}") for i in range(2 * SLICE + 10)]
    removes = [ticker.add(c) for c in cams]
    try:
        await eventually(lambda: cams[-2].states >= 1, 10, "the first tick's end")
    finally:
        await ticker.close()
    first_tick = order[: order.index(cams[-2].name) + 1]
    assert first_tick.index("other") == SLICE  # after the first slice, before the second
    assert [n for n in first_tick if n != "other"] == [c.name for c in cams[:-1]]  # each once, in order
    assert cams[-1].states == 0  # removed while a slice waited: not checked
