"""One event-loop timer for many simulators in one process (`topgimbal sim --fleet N`, issue 45).

A simulator keeps one timer for the earliest thing it has due (a stream frame, a delayed packet).
With a thousand simulators in one process that was a thousand asyncio TimerHandles, re-armed
50,000 times a second at 50 Hz: `call_later`'s handle objects and the loop's heap of them,
ordered by a Python `__lt__` (about ten calls per push and pop; `_schedule` and that heap were
about a fifth of the fleet's time under cProfile). Sharing one took about 9 % off the CPU of a
250-camera fleet (docs/fleet.md). Here the simulators of one loop share one handle: their wake-ups sit in a
heap of plain tuples (compared in C), and one loop timer stands for the earliest of them. When it
fires, every wake-up due by then runs, in time order, in the same callback.

A wake-up is an `Entry` with `cancel()`, as a TimerHandle has: a simulator holds either kind.
Cancelled entries stay in the heap until they come up (or a compaction drops them), so cancelling
costs nothing; the heap is bounded by compacting when dead entries outnumber the live ones.

Times are the running loop's (`loop.time()`, the scale `call_at` takes): a virtual-time loop
moves them with everything else.
"""

from __future__ import annotations

import asyncio
import heapq
import logging
from collections.abc import Callable

from ..clock import MonotonicFn, loop_clock

log = logging.getLogger("topgimbal.sim")

COMPACT_SLACK = 64  # dead entries tolerated beyond the live ones before the heap is rebuilt


class Entry:
    """One wake-up; `cancel()` as `asyncio.TimerHandle.cancel()`."""

    __slots__ = ("callback", "cancelled", "owner")

    def __init__(self, callback: Callable[[], None], owner: SharedTimer) -> None:
        self.callback = callback
        self.cancelled = False
        self.owner = owner

    def cancel(self) -> None:
        if not self.cancelled:
            self.cancelled = True
            self.owner.live -= 1


class SharedTimer:
    """Wake-ups for many callers on one loop timer. Made on (or first used from) a running loop."""

    def __init__(self) -> None:
        self._heap: list[tuple[float, int, Entry]] = []
        self._seq = 0
        self.live = 0  # entries neither cancelled nor run
        self.fired = 0  # loop timer callbacks so far (each runs every wake-up due by then)
        self.ran = 0  # wake-ups run so far
        self._handle: asyncio.TimerHandle | None = None
        self._armed_at: float | None = None
        self._loop: asyncio.AbstractEventLoop | None = None
        self._now: MonotonicFn | None = None  # the loop's clock (clock.loop_clock), bound on first use
        self._firing = False  # in _fire: it arms the loop timer once at its end

    def __len__(self) -> int:
        return self.live

    def time(self) -> float:
        """The loop's time, the scale `call_at` takes."""
        self._running_loop()
        assert self._now is not None
        return self._now()

    def call_at(self, when: float, callback: Callable[[], None]) -> Entry:
        """Run `callback()` at loop time `when` (at once on the next fire if that has passed)."""
        loop = self._running_loop()
        entry = Entry(callback, self)
        self._seq += 1
        heapq.heappush(self._heap, (when, self._seq, entry))
        self.live += 1
        if len(self._heap) > 2 * self.live + COMPACT_SLACK:
            self._heap[:] = [e for e in self._heap if not e[2].cancelled]  # in place: _fire holds it
            heapq.heapify(self._heap)
        if not self._firing and (self._armed_at is None or when < self._armed_at):
            self._arm(loop, when)
        return entry

    def close(self) -> None:
        """Nothing more runs (the entries still pending are dropped)."""
        if self._handle is not None:
            self._handle.cancel()
        self._handle = self._armed_at = None
        for _, _, entry in self._heap:
            entry.cancelled = True
        self._heap.clear()
        self.live = 0

    def _running_loop(self) -> asyncio.AbstractEventLoop:
        loop = self._loop
        if loop is None:
            loop = self._loop = asyncio.get_running_loop()
            self._now = loop_clock(loop)
        return loop

    def _arm(self, loop: asyncio.AbstractEventLoop, when: float) -> None:
        if self._handle is not None:
            self._handle.cancel()
        self._armed_at = when
        self._handle = loop.call_at(when, self._fire)

    def _fire(self) -> None:
        armed_at = self._armed_at
        self._handle = self._armed_at = None
        loop = self._loop
        assert loop is not None
        self.fired += 1
        heap = self._heap
        # The loop runs a timer once its time is within the clock's resolution: what it was armed
        # for counts as come, or the same entry would re-arm (and fire) again until time moves.
        assert self._now is not None
        now = self._now()
        if armed_at is not None and armed_at > now:
            now = armed_at
        # Only what was in the heap when this fire began: a wake-up that a callback schedules for
        # now or earlier waits for the next fire (which is at once), so a caller that keeps asking
        # for "now" cannot hold the loop here.
        budget = len(heap)
        self._firing = True
        try:
            self._run_due(now, budget)
        finally:
            self._firing = False
        while heap and heap[0][2].cancelled:
            heapq.heappop(heap)
        if heap:
            self._arm(loop, heap[0][0])

    def _run_due(self, now: float, budget: int) -> None:
        heap = self._heap
        while heap and budget > 0:
            when, _, entry = heap[0]
            if when > now:
                break
            heapq.heappop(heap)
            budget -= 1
            if entry.cancelled:
                continue
            entry.cancelled = True
            self.live -= 1
            self.ran += 1
            try:
                entry.callback()
            except Exception:  # one simulator's fault is not the fleet's
                log.exception("a simulator's timer callback failed")


__all__ = ["Entry", "SharedTimer"]
