"""Clocks the simulator reads time from.

The device core never calls `time` itself: it is handed a clock, so tests can drive physics and
streams deterministically with `FakeClock` while servers use the event loop's monotonic time.
"""

from __future__ import annotations

import asyncio
from typing import Protocol

from ..clock import FakeClock, MonotonicFn, loop_clock, monotonic

__all__ = ["Clock", "FakeClock", "MonotonicClock"]  # FakeClock: the one in topgimbal.clock (it has now())


class Clock(Protocol):
    def now(self) -> float:
        """Seconds on a monotonic scale (only differences matter)."""
        ...


class MonotonicClock:
    """Real time: `topgimbal.clock.monotonic`, the running loop's own time, so deadlines computed
    from this clock can be handed to `loop.call_at` unchanged (and a virtual-time loop moves them)."""

    __slots__ = ("_read",)

    def __init__(self) -> None:
        self._read: MonotonicFn = monotonic

    def now(self) -> float:
        return self._read()

    def bind(self, loop: asyncio.AbstractEventLoop | None) -> None:
        """Read `loop`'s time directly (no running-loop lookup per read: a fleet's simulators read
        it several times a frame) while the simulator serves on it; None: `monotonic` again."""
        self._read = monotonic if loop is None else loop_clock(loop)
