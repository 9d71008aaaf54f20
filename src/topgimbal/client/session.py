"""Request/response matching, retries and timeouts, with no I/O and an injected clock.

The TOP protocol has no transaction id: a reply is the frame with the same identifier, the same
control (`r`/`w`) and swapped addresses. This module is the only place that decides which frame
answers which request. The rules:

- At most one outstanding request per (identifier, destination): the caller serialises on `key`.
- Every send of a request (first try and retries) is an *attempt* in a per-key FIFO. A reply
  answers the oldest attempt still waiting. If that attempt belongs to a request that has
  already finished (timed out, or answered by a retry), the reply is *late*: it is counted and
  dropped, never handed to the request now pending (the pymodbus #538 bug).
- An attempt whose reply has not come `late_window_s` after it was sent is assumed lost.
- A write's echo must carry the data that was sent (when it has the same length): an echo of an
  older set-point is not the answer to a newer one; it answers the oldest attempt with its data.
- A read answer byte-identical to the previous answer on the same key, arriving after the next
  attempt was sent but sooner than half the fastest round trip seen, cannot be that attempt's
  answer: it is a network duplicate and does not consume the attempt.
- `ERE` (the device's error answer) fails the oldest waiting attempt sent to that address.
- `fail_all` ends every pending request at once (disconnect, aioesphomeapi #498).
"""

from __future__ import annotations

import itertools
from collections import deque
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

from ..errors import DeviceError, RequestTimeoutError
from ..protocol import Dialect, Frame, Message

Key = tuple[str, str]  # (identifier, destination address)
Clock = Callable[[], float]


@dataclass
class LinkStats:
    """Link counters. `as_dict()` is JSON-able and is what the console and `monitor` show."""

    frames_in: int = 0
    frames_out: int = 0
    bytes_in: int = 0
    bytes_out: int = 0
    requests: int = 0
    replies: int = 0
    timeouts: int = 0
    retries: int = 0
    late_replies: int = 0
    duplicates: int = 0
    stray_replies: int = 0
    errors: int = 0
    bad_frames: int = 0
    rtt_ms_last: float | None = None
    rtt_ms_avg: float | None = None
    rtt_ms_min: float | None = None
    connected: bool = False

    def add_rtt(self, rtt_s: float) -> None:
        ms = rtt_s * 1000.0
        self.rtt_ms_last = ms
        # exponential average: a link's recent behaviour matters more than its history
        self.rtt_ms_avg = ms if self.rtt_ms_avg is None else self.rtt_ms_avg * 0.9 + ms * 0.1
        self.rtt_ms_min = ms if self.rtt_ms_min is None else min(self.rtt_ms_min, ms)

    def as_dict(self) -> dict[str, Any]:
        d = dict(self.__dict__)
        for k in ("rtt_ms_last", "rtt_ms_avg", "rtt_ms_min"):
            if d[k] is not None:
                d[k] = round(d[k], 3)
        return d


_ids = itertools.count(1)


@dataclass(eq=False)
class Pending:
    """One request in flight. `waiter` is a slot for the I/O layer (an asyncio future)."""

    frame: Frame
    key: Key
    timeout_s: float
    retries: int
    expect_reply: bool = True
    id: int = field(default_factory=lambda: next(_ids))
    attempts: int = 0
    first_sent_at: float | None = None
    last_sent_at: float | None = None
    deadline: float | None = None
    done: bool = False
    reply: Message | None = None
    error: Exception | None = None
    waiter: Any = None

    @property
    def idempotent_retries_left(self) -> int:
        return self.retries + 1 - self.attempts


@dataclass
class _Attempt:
    pending: Pending
    sent_at: float
    data: bytes


@dataclass(frozen=True)
class Received:
    """What the session made of one incoming frame."""

    message: Message
    matched: Pending | None = None  # the request this frame answered (now done)
    late: bool = False  # answers an attempt of a request that had already finished
    duplicate: bool = False
    stray: bool = False  # looks like a reply (same key) but fits no waiting attempt


class Session:
    """Pure matching state for one connection."""

    def __init__(
        self,
        dialect: Dialect,
        *,
        clock: Clock,
        late_window_s: float = 2.0,
        dup_window_s: float = 0.25,
        dup_floor_cap_s: float = 0.0002,
        stats: LinkStats | None = None,
    ) -> None:
        self.dialect = dialect
        self.clock = clock
        self.late_window_s = late_window_s
        self.dup_window_s = dup_window_s
        self.dup_floor_cap_s = dup_floor_cap_s
        self.stats = stats or LinkStats()
        self.pending: dict[Key, Pending] = {}
        self._attempts: dict[tuple[str, str, str], deque[_Attempt]] = {}
        self._last_answer: dict[tuple[str, str, str], tuple[bytes, float]] = {}
        self._recent_timeouts: dict[tuple[str, str, str], float] = {}

    # -- requests ------------------------------------------------------------------------------

    @staticmethod
    def key_of(frame: Frame) -> Key:
        return (frame.ident, frame.dst)

    def open(self, frame: Frame, *, timeout_s: float, retries: int, expect_reply: bool = True) -> Pending:
        """Register a request before its first send. Raises if its key already has one."""
        key = self.key_of(frame)
        if key in self.pending:
            raise RuntimeError(f"a {key[0]} request to {key[1]} is already outstanding (serialise on Session.key_of)")
        p = Pending(frame, key, timeout_s, retries if expect_reply else 0, expect_reply)
        if expect_reply:
            self.pending[key] = p
        self.stats.requests += 1
        return p

    def sent(self, p: Pending) -> None:
        """Record one attempt of `p` as sent now (call after the bytes left)."""
        now = self.clock()
        p.attempts += 1
        if p.attempts > 1:
            self.stats.retries += 1
        if p.first_sent_at is None:
            p.first_sent_at = now
        p.last_sent_at = now
        if not p.expect_reply:
            p.done = True
            return
        p.deadline = now + p.timeout_s
        self._attempts.setdefault(self._fifo_key(p.frame), deque()).append(_Attempt(p, now, p.frame.data))

    def next_deadline(self) -> float | None:
        live = [p.deadline for p in self.pending.values() if p.deadline is not None and not p.done]
        return min(live) if live else None

    def expire(self) -> list[tuple[Pending, str]]:
        """Requests past their deadline: ("retry", p) means send `p.frame` again then call
        `sent(p)`; ("timeout", p) means `p` is finished with `p.error` set."""
        now = self.clock()
        out: list[tuple[Pending, str]] = []
        for p in list(self.pending.values()):
            if p.done or p.deadline is None or now < p.deadline:
                continue
            if p.attempts <= p.retries:
                p.deadline = None  # until the caller re-sends
                out.append((p, "retry"))
            else:
                self.stats.timeouts += 1
                waited = now - (p.first_sent_at or now)
                what = "attempt" if p.attempts == 1 else "attempts"
                self._finish(
                    p,
                    error=RequestTimeoutError(
                        f"no reply to {p.frame.ident} ({p.frame.text()}) after {p.attempts} {what} in {waited:.2f} s"
                    ),
                )
                self._recent_timeouts[self._fifo_key(p.frame)] = now
                out.append((p, "timeout"))
        return out

    def cancel(self, p: Pending, error: Exception | None = None) -> None:
        """The caller gave up on `p` (task cancelled): its attempts stay in the FIFO so a reply
        that still comes is recognised as late rather than given to the next request."""
        if not p.done:
            self._finish(p, error=error)

    def fail_all(self, error: Exception) -> list[Pending]:
        """End every pending request with `error` (the link is gone)."""
        failed = [p for p in self.pending.values() if not p.done]
        for p in failed:
            self._finish(p, error=error)
        self.pending.clear()
        self._attempts.clear()
        return failed

    # -- incoming ------------------------------------------------------------------------------

    def receive(self, message: Message) -> Received:
        """Classify one decoded incoming frame; updates the matched request if any."""
        frame = message.frame
        now = self.clock()
        if message.is_error:
            return self._receive_error(message, now)
        fk = (frame.ident, frame.src, frame.rw)
        queue = self._attempts.get(fk)
        self._prune(queue, now)
        if not queue:
            self._recent_answer(fk, frame, now)
            late = self._was_timed_out(fk, now)
            if late:
                self.stats.late_replies += 1
            return Received(message, late=late)
        if frame.rw == "r":
            last = self._last_answer.get(fk)
            oldest = queue[0]
            # A copy of the previous answer that arrives sooner after the oldest attempt than half
            # the fastest round trip ever seen cannot be that attempt's answer: a network duplicate.
            # Capped, so that a slow first round trip cannot make later fast answers look like copies.
            floor = min(0.5 * (self.stats.rtt_ms_min or 0.0) / 1000.0, self.dup_floor_cap_s)
            if (
                last is not None
                and last[0] == frame.data
                and now - last[1] <= self.dup_window_s
                and oldest.sent_at >= last[1]
                and now - oldest.sent_at < floor
            ):
                self.stats.duplicates += 1
                return Received(message, duplicate=True)
        else:
            same_length = [a for a in queue if len(a.data) == len(frame.data)]
            if same_length:
                # An echo answers the oldest attempt that sent these very data; older attempts it
                # overtakes are presumed lost (their echoes, if they still come, are strays).
                hit = next((a for a in same_length if a.data.upper() == frame.data.upper()), None)
                if hit is None:
                    self.stats.stray_replies += 1
                    return Received(message, stray=True)
                while queue[0] is not hit:
                    queue.popleft()
        attempt = queue.popleft()
        self._recent_answer(fk, frame, now)
        p = attempt.pending
        if p.done:
            self.stats.late_replies += 1
            return Received(message, late=True)
        self.stats.replies += 1
        self.stats.add_rtt(now - attempt.sent_at)
        self._finish(p, reply=message)
        return Received(message, matched=p)

    def _receive_error(self, message: Message, now: float) -> Received:
        self.stats.errors += 1
        src = message.frame.src
        best: tuple[float, tuple[str, str, str]] | None = None
        for fk, queue in self._attempts.items():
            self._prune(queue, now)
            if fk[1] == src and queue and (best is None or queue[0].sent_at < best[0]):
                best = (queue[0].sent_at, fk)
        if best is None:
            return Received(message)
        attempt = self._attempts[best[1]].popleft()
        p = attempt.pending
        if p.done:
            return Received(message, late=True)
        self._finish(p, error=DeviceError(f"the device rejected {p.frame.ident} ({p.frame.text()}) with ERE"))
        return Received(message, matched=p)

    # -- internals -----------------------------------------------------------------------------

    @staticmethod
    def _fifo_key(frame: Frame) -> tuple[str, str, str]:
        # replies come from the address the request went to, with the same control character
        return (frame.ident, frame.dst, frame.rw or "w")

    def _prune(self, queue: deque[_Attempt] | None, now: float) -> None:
        while queue and now - queue[0].sent_at > self.late_window_s:
            queue.popleft()

    def _recent_answer(self, fk: tuple[str, str, str], frame: Frame, now: float) -> None:
        if frame.rw == "r":
            self._last_answer[fk] = (frame.data, now)

    def _was_timed_out(self, fk: tuple[str, str, str], now: float) -> bool:
        t = self._recent_timeouts.get(fk)
        if t is None:
            return False
        if now - t > max(self.late_window_s * 5, 10.0):
            del self._recent_timeouts[fk]
            return False
        return True

    def _finish(self, p: Pending, *, reply: Message | None = None, error: Exception | None = None) -> None:
        p.done = True
        p.reply = reply
        p.error = error
        p.deadline = None
        if self.pending.get(p.key) is p:
            del self.pending[p.key]
