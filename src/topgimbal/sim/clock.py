"""Clocks the simulator reads time from.

The device core never calls `time` itself: it is handed a clock, so tests can drive physics and
streams deterministically with `FakeClock` while servers use the event loop's monotonic time.
"""

from __future__ import annotations

from typing import Protocol

from ..clock import monotonic


class Clock(Protocol):
    def now(self) -> float:
        """Seconds on a monotonic scale (only differences matter)."""
        ...


class MonotonicClock:
    """Real time: `topgimbal.clock.monotonic`, the running loop's own time, so deadlines computed
    from this clock can be handed to `loop.call_at` unchanged (and a virtual-time loop moves them)."""

    def now(self) -> float:
        return monotonic()


class FakeClock:
    """Time that only moves when a test says so."""

    def __init__(self, start: float = 0.0) -> None:
        self._t = float(start)

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
