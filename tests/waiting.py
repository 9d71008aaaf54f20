"""The tests' one way to wait for something: poll `read()` until `ok(value)` holds, within `bound_s`.

The bound is a bound on a hang, never a speed assertion (speed is measured in bench/). A wait that
runs out fails with what it waited for and the last values it saw, oldest first, so a failure says
how far off it was (an axis 0.5013 deg from its target is not "condition did not hold").

`near()` is the form for a live value against a target: the margin is in its signature, and the test
says where it comes from (what it measured, a settled value, the product's own tolerance plus what
the live value may lag behind the reported one) rather than re-using a product tolerance as is.

Time is `topgimbal.clock.monotonic`: the running loop's own, so on looptime's virtual-time loop a
wait costs no real time; in a thread, `time.monotonic`.
"""

from __future__ import annotations

import asyncio
import time
from collections.abc import Callable
from typing import Any, TypeVar

from topgimbal.clock import monotonic

T = TypeVar("T")
LAST_SEEN = 5  # distinct values kept for the failure message
EVERY_S = 0.02  # polling period: short beside any bound here
# A simulated axis at rest: sim/physics.py arrives exactly on its goal (it never overshoots); the
# goal itself is the target as the protocol encodes it (hundredths of a degree at the coarsest).
SETTLED_DEG = 0.05


class WaitTimeoutError(AssertionError):
    """What a test waited for did not happen within its bound."""


class _Seen:
    def __init__(self) -> None:
        self.values: list[Any] = []

    def add(self, value: Any) -> None:
        if not self.values or self.values[-1] != value:
            self.values.append(value)
            del self.values[:-LAST_SEEN]

    def error(self, what: str, bound_s: float) -> WaitTimeoutError:
        shown = ", ".join(_short(v) for v in self.values) or "(never read)"
        return WaitTimeoutError(f"{what}: not within {bound_s:g} s; last values seen, oldest first: {shown}")


def _short(value: Any) -> str:
    text = repr(value)
    return text if len(text) <= 200 else text[:197] + "..."


def _truthy(value: Any) -> bool:
    return bool(value)


async def until(
    what: str, read: Callable[[], T], ok: Callable[[T], bool] = _truthy, *, bound_s: float, every_s: float = EVERY_S
) -> T:
    """Poll `read()` in the event loop until `ok(value)`; return that value."""
    seen = _Seen()
    end = monotonic() + bound_s
    while True:
        value = read()
        if ok(value):
            return value
        seen.add(value)
        if monotonic() > end:
            raise seen.error(what, bound_s)
        await asyncio.sleep(every_s)


def until_blocking(
    what: str, read: Callable[[], T], ok: Callable[[T], bool] = _truthy, *, bound_s: float, every_s: float = 0.05
) -> T:
    """`until` for a test that is not in the event loop (a thread, the blocking facade)."""
    seen = _Seen()
    end = time.monotonic() + bound_s
    while True:
        value = read()
        if ok(value):
            return value
        seen.add(value)
        if time.monotonic() > end:
            raise seen.error(what, bound_s)
        time.sleep(every_s)


async def near(what: str, read: Callable[[], float], target: float, *, margin: float, bound_s: float) -> float:
    """Wait until the live value `read()` is within `margin` of `target`; return it."""
    return await until(
        f"{what} within {margin:g} of {target:g}", read, lambda v: abs(v - target) <= margin, bound_s=bound_s
    )


async def settled(what: str, read: Callable[[], float], *, still: float, apart_s: float, bound_s: float) -> float:
    """Wait until two reads `apart_s` apart differ by less than `still` (a live value at rest); return
    the second."""
    seen = _Seen()
    end = monotonic() + bound_s
    before = read()
    while True:
        await asyncio.sleep(apart_s)
        now = read()
        if abs(now - before) < still:
            return now
        seen.add(now)
        if monotonic() > end:
            raise seen.error(f"{what} at rest (two reads {apart_s:g} s apart within {still:g})", bound_s)
        before = now
