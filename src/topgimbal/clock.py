"""The one clock: every deadline, age and rate in topgimbal reads time through this module.

Time is a dependency, not a global: objects take a `clock` (a `MonotonicFn`) and default to
`monotonic`, which is the running event loop's own clock. A virtual-time loop in a test (looptime,
or any loop whose `time()` is fake) therefore moves every deadline in the client, the simulator,
the bridge and the video path at once, with no real waiting. Outside a loop (a thread, the sync
facade's caller) it is `time.monotonic`, which is what asyncio's default loop uses, so the two agree.

Wall-clock time (UTC for EXIF dates, MAVLink time fields, log stamps) is `wall_time`; nothing may
use it to measure an interval. `tests/test_architecture.py` allows direct calls of `time.monotonic`,
`time.time`, `time.perf_counter` and `loop.time` only here and in a named allow-list.
"""

from __future__ import annotations

import asyncio
import time
from collections.abc import Callable

MonotonicFn = Callable[[], float]
"""A clock: seconds on a monotonic scale (only differences matter)."""


def monotonic() -> float:
    """The running event loop's time, or `time.monotonic()` where no loop runs in this thread."""
    try:
        return asyncio.get_running_loop().time()
    except RuntimeError:
        return time.monotonic()


def loop_clock(loop: asyncio.AbstractEventLoop) -> MonotonicFn:
    """`loop`'s own time as a MonotonicFn, bound once: what `monotonic` returns inside that loop,
    without finding the running loop on every read (a per-datagram path reads it once a frame)."""
    return loop.time


def reads_system_monotonic(loop: asyncio.AbstractEventLoop) -> bool:
    """Whether `loop.time()` reads CLOCK_MONOTONIC (asyncio's own loops, and a test loop whose
    virtual time is off), not a time of its own (a virtual-time loop starts at 0 and jumps): what a
    kernel timer set on CLOCK_MONOTONIC (sim/precise_timer.py) needs. Judged by the reading, since a
    test loop's class is patched whether its time is virtual or not."""
    return abs(loop.time() - time.monotonic()) < 0.005


def wall_time() -> float:
    """UTC seconds since the epoch: for dates written somewhere, never for intervals."""
    return time.time()


class FakeClock:
    """Time that moves only when a test says so; callable, so it is a `MonotonicFn` itself."""

    def __init__(self, start: float = 0.0) -> None:
        self._t = float(start)

    def __call__(self) -> float:
        return self._t

    def now(self) -> float:
        return self._t

    def advance(self, dt: float) -> float:
        if dt < 0:
            raise ValueError(f"a clock cannot go back (dt={dt})")
        self._t += dt
        return self._t

    def set(self, t: float) -> None:
        if t < self._t:
            raise ValueError(f"a clock cannot go back ({t} < {self._t})")
        self._t = t
