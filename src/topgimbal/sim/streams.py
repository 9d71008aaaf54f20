"""Periodic reports hosts subscribed to (attitude streams, temperature and range reports).

A `Stream` knows whom it goes to and which function builds its frames, so the device sends any
kind of stream without knowing what it carries. `Streams` keeps them by (peer, identifier) and in a
heap by due time, so finding what is due costs the same with one subscriber or thousands.
"""

from __future__ import annotations

import heapq
from collections.abc import Callable, Hashable
from dataclasses import dataclass, field
from typing import Any

from ..protocol import Frame

Key = tuple[Hashable, str]
# Builds a stream's frames at its due time from the device's state (`context.SimState`; typed
# there as `context.ReportFn`, this module only stores it).
ReportFn = Callable[[Any, "Stream"], list[Frame]]


@dataclass(eq=False, slots=True)
class Stream:
    """One host's subscription. `memo_*` let a report reuse its frames while the values it would
    send are unchanged (an attitude stream of a gimbal at rest); `last_*` let the device reuse the
    bytes it encoded them to."""

    peer: Hashable
    ident: str  # identifier of the frames sent (GAC, GIA, LRF, TMP)
    host: str  # address letter of the host (U or P)
    period: float
    next_due: float
    report: ReportFn
    memo_key: Hashable = None  # what memo_frames were built from (compared, never read)
    memo_frames: list[Frame] = field(default_factory=list)
    last_frames: list[Frame] | None = None
    last_data: list[bytes] = field(default_factory=list)
    heap_seq: int = -1  # the heap entry that is current for this stream (older ones are stale)


class Streams:
    def __init__(self) -> None:
        self.by_key: dict[Key, Stream] = {}
        self._heap: list[tuple[float, int, Stream]] = []
        self._seq = 0

    def __len__(self) -> int:
        return len(self.by_key)

    def subscribe(
        self, peer: Hashable, ident: str, host: str, rate_hz: float, now: float, report: ReportFn
    ) -> Stream | None:
        """Start, retime or (rate 0) end `peer`'s stream of `ident`. A retimed stream keeps its
        phase when that is sooner, so switching rates never skips a frame."""
        key = (peer, ident)
        if rate_hz <= 0:
            self.by_key.pop(key, None)
            return None
        period = 1.0 / rate_hz
        old = self.by_key.get(key)
        first = now + period if old is None else min(old.next_due, now + period)
        s = Stream(peer, ident, host, period, first, report)
        self.by_key[key] = s
        self.push(s)
        return s

    def subscribed(self, peer: Hashable, ident: str) -> bool:
        return (peer, ident) in self.by_key

    def forget(self, peer: Hashable) -> None:
        for key in [k for k in self.by_key if k[0] == peer]:
            del self.by_key[key]

    def clear(self) -> None:
        self.by_key.clear()
        self._heap.clear()

    def push(self, s: Stream) -> None:
        self._seq += 1
        s.heap_seq = self._seq
        heapq.heappush(self._heap, (s.next_due, self._seq, s))
        if len(self._heap) > 4 * len(self.by_key) + 64:
            self._compact()

    def _live(self, entry: tuple[float, int, Stream]) -> bool:
        s = entry[2]
        return entry[1] == s.heap_seq and self.by_key.get((s.peer, s.ident)) is s

    def _compact(self) -> None:
        self._heap = [e for e in self._heap if self._live(e)]
        heapq.heapify(self._heap)

    def next_due(self) -> float | None:
        heap = self._heap
        while heap and not self._live(heap[0]):
            heapq.heappop(heap)
        return heap[0][0] if heap else None

    def pop_due(self, limit: float) -> Stream | None:
        """The earliest stream due at or before `limit`, taken off the heap (`push` it back after
        moving its due time on), or None."""
        heap = self._heap
        while heap:
            entry = heap[0]
            if not self._live(entry):
                heapq.heappop(heap)
                continue
            if entry[0] > limit:
                return None
            heapq.heappop(heap)
            return entry[2]
        return None

    def alive(self, s: Stream) -> bool:
        return self.by_key.get((s.peer, s.ident)) is s


__all__ = ["Key", "ReportFn", "Stream", "Streams"]
