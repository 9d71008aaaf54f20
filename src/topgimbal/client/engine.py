"""The transaction engine: which frame answers which request. No I/O; an injected clock.

The TOP protocol has no transaction id: an answer has the request's identifier and control, comes
from the address the request went to and, for a write, carries the data sent (or, where the model
profile says so, a report of the outcome: `acks.EchoPolicy`). The rest is timing. In short (the
reasoning is in docs/client.md, "Matching"):

- One live request per (identifier, device address); later ones wait in a FIFO. Every send is an
  attempt, kept per (identifier, address, control) for `late_window_s` or until answered.
- A reply to ANY attempt of the live request completes it. A read is deferred until no earlier
  request's attempt can still be answered; a non-idempotent write (photo, toggle, step) is sent
  once, on a quiet key. An echo with data no attempt sent fails the write (DeviceError).
- A frame sooner after a read than half the fastest round trip is a network copy; ERE fails a
  request only when it is the only one it can answer; frames with a recovered length character
  answer only where the profile says the firmware gets it wrong (`roles.recovered_ok`).
- Pacing: no two frames closer than the model's `min_command_gap_s` (C12: 40 ms), whoever sends
  them; a set-point sent without waiting replaces one still waiting for its turn.
- Slow answers (`slow_answers`, C12 MOD) are constants: never deferred, never retried, blocking
  nothing; an answer after the request gave up still reaches the state cache.
"""

from __future__ import annotations

import copy
import math
from collections import deque
from collections.abc import Mapping

from ..errors import RequestTimeoutError, TopGimbalError
from ..protocol import DeviceModel, Dialect, Frame, Message
from . import roles
from .acks import EchoPolicy
from .matching import Matching
from .records import Attempt, Clock, EchoRule, Inbound, Key, Ledger, Pacer, RKey, Transaction, timeout_text
from .stats import LinkStats

__all__ = ["Attempt", "Engine", "Inbound", "Key", "Ledger", "RKey", "Transaction"]

MAX_WAITING = 256  # requests queued behind one key (a runaway caller gets an error, not a leak)


class Engine(Matching):
    __slots__ = ("_finished", "_out", "_waiting", "echo_rules", "pacer")  # with Matching's

    def __init__(
        self,
        *,
        clock: Clock,
        late_window_s: float = 2.0,
        dup_window_s: float = 0.05,
        stats: LinkStats | None = None,
        model: DeviceModel | None = None,
        dialect: Dialect | None = None,
        min_gap_s: float | None = None,
    ) -> None:
        """`model` (with its `dialect`) brings the profile's acknowledgement rules, the answers
        known to come with a wrong length, and the pacing (`min_gap_s` overrides it)."""
        self.clock = clock
        self.late_window_s = late_window_s
        self.dup_window_s = dup_window_s
        self.stats = stats if stats is not None else LinkStats()
        self.echo_rules = EchoPolicy(model)
        self.echo_matches: EchoRule = self.echo_rules
        self.recovered_ok = roles.recovered_ok(dialect, model) if model and dialect else frozenset()
        gap = min_gap_s if min_gap_s is not None else (model.min_command_gap_s if model is not None else 0.0)
        self.pacer = Pacer(gap)
        self.live: dict[Key, Transaction] = {}
        self._waiting: dict[Key, deque[Transaction]] = {}
        self._ledger: dict[RKey, Ledger] = {}
        self._last_frame: dict[RKey, tuple[float, bytes]] = {}  # time and data of the last frame
        self._last_error: dict[str, float] = {}  # device address -> when its last ERE came
        self.copies_seen = False  # the link has delivered a frame twice
        self._rtt_samples = 0
        self._streams: dict[str, float] = {}  # identifier -> until when its frames come unasked
        self._out: list[Frame] = []
        self._finished: list[Transaction] = []

    # -- requests --------------------------------------------------------------------------------

    def submit(
        self,
        frame: Frame,
        *,
        timeout_s: float,
        retries: int = 0,
        expect_reply: bool = True,
        exclusive: bool = False,
        fields: Mapping[str, object] | None = None,
        slow: bool = False,
        lenient: bool = False,
        background: bool = False,
    ) -> Transaction:
        """Register a request (arguments already validated). Its frames come out of
        `take_frames()`; it ends up in `take_finished()`. `slow`: a query of a constant that the
        device may answer very late or never (see the module docstring). `lenient`: its answer
        may come with a wrong length character (an identity probe in another model's dialect).
        `background`: a periodic feed frame, which a paced queue lets other frames pass (Pacer)."""
        now = self.clock()
        # Sent once, a non-idempotent request waits as long in all as a retried one would.
        wait_s = timeout_s * (retries + 1) if exclusive else timeout_s
        once = exclusive or not expect_reply or slow
        tx = Transaction(frame, wait_s, 0 if once else retries, expect_reply, exclusive)
        tx.fields, tx.submitted_at, tx.slow, tx.lenient, tx.background = fields, now, slow, lenient, background
        self.stats.requests += 1
        if not expect_reply:
            self._send(tx, now)  # fire and forget: never live, so it queues behind nothing
            return tx
        key = tx.key
        if key in self.live:
            queue = self._waiting.setdefault(key, deque())
            if len(queue) >= MAX_WAITING:
                raise TopGimbalError(
                    f"{len(queue)} {key[0]} requests to {key[1]} are already waiting; slow down", request=frame
                )
            queue.append(tx)
        else:
            self._start(tx, now)
        return tx

    def cancel(self, tx: Transaction, error: Exception | None = None) -> None:
        """The caller gave up on `tx`. Attempts already sent stay in the ledger: a reply that
        still comes is recognised as late rather than taken by the next request."""
        if tx.done:
            return
        queue = self._waiting.get(tx.key)
        if tx.state == "queued" and queue is not None and tx in queue:
            queue.remove(tx)
            tx.state, tx.error = "done", with_request(error, tx.frame)
            return
        self._finish(tx, self.clock(), error=error)

    def fail_all(self, error: Exception) -> list[Transaction]:
        """End every live and waiting request with `error` (the link is gone)."""
        failed = [*self.live.values(), *(t for q in self._waiting.values() for t in q)]
        self._waiting.clear()
        self.live.clear()
        self.pacer.clear()
        for tx in failed:
            if not tx.done:
                tx.state, tx.error, tx.deadline = "done", with_request(error, tx.frame), None
                tx.attempts = []
                self._finished.append(tx)
        return failed

    def reset(self) -> None:
        """A new connection (TCP, serial): nothing sent on the old one can be answered on it."""
        self._ledger.clear()
        self._last_frame.clear()
        self._last_error.clear()

    def set_stream(self, ident: str, on: bool) -> None:
        """A telemetry stream of `ident` frames is on (or went off: its frames may still come for
        `late_window_s`). On its key a frame is a sample, not a copy, and it answers the live read
        (docs/client.md, "Telemetry"): reads there are neither deferred nor taken for copies."""
        if on:
            self._streams[ident] = math.inf
        elif ident in self._streams:
            self._streams[ident] = self.clock() + self.late_window_s

    def _streaming(self, ident: str, now: float) -> bool:
        until = self._streams.get(ident)
        return until is not None and now < until

    def take_frames(self) -> list[Frame]:
        out, self._out = self._out, []
        return out

    def take_finished(self) -> list[Transaction]:
        out, self._finished = self._finished, []
        return out

    def next_deadline(self) -> float | None:
        best = self.pacer.next_deadline()
        for tx in self.live.values():
            d = tx.deadline
            if d is not None and (best is None or d < best):
                best = d
        return best

    def on_tick(self) -> None:
        """Paced frames, retries, timeouts and the end of deferrals that are due now."""
        now = self.clock()
        while (paced := self.pacer.due(now)) is not None:
            self._emit(paced, now)
        for tx in [t for t in self.live.values() if t.deadline is not None and t.deadline <= now]:
            if tx.state == "deferred":
                self._start(tx, now)
            elif tx.state == "sent":
                if len(tx.attempts) <= tx.retries:
                    self.stats.retries += 1
                    self._send(tx, now)
                else:
                    self.stats.timeouts += 1
                    self._finish(tx, now, error=RequestTimeoutError(timeout_text(tx, now)))

    # -- internals ----------------------------------------------------------------------------------

    def _close(self, attempt: Attempt) -> None:
        ledger = self._ledger.get(attempt.tx.rkey)
        if ledger is not None:
            ledger.close(attempt)
        else:
            attempt.closed = True

    def _start(self, tx: Transaction, now: float) -> None:
        self.live[tx.key] = tx
        until = self._blocked_until(tx, now)
        if until is not None:
            if tx.state != "deferred":
                self.stats.deferred += 1
            tx.state, tx.deadline = "deferred", until
            return
        self._send(tx, now)

    def _blocked_until(self, tx: Transaction, now: float) -> float | None:
        """When `tx` may be sent without an earlier request's answer passing for its own."""
        if (
            (tx.frame.rw == "w" and not tx.exclusive)
            or tx.slow
            or (tx.frame.rw == "r" and self._streaming(tx.frame.ident, now))
        ):
            return None  # (on a streaming key every sample answers: nothing to wait for)
        until: float | None = None
        ledger = self._ledger.get(tx.rkey)
        # A write's echo carries its data: an earlier write of other data cannot be taken for it
        # (unless the profile says its acknowledgement is a report, which carries other data).
        by_data = tx.frame.rw == "w" and tx.frame.ident not in self.echo_rules.rules
        if ledger is not None:
            window = now - self.late_window_s
            for a in ledger.open:
                if by_data and a.tx.frame.data.upper() != tx.frame.data.upper():
                    continue
                if a.sent_at >= window and a.tx is not tx:
                    end = a.sent_at + self.late_window_s
                    until = end if until is None else max(until, end)
        if tx.exclusive or self.copies_seen:
            # Quiet first: a copy of an earlier frame may still be on its way (only a link that
            # has shown copies delays queries for this; photos and toggles always wait).
            last = self._last_frame.get(tx.rkey)
            if last is not None and now - last[0] < self.dup_window_s:
                end = last[0] + self.dup_window_s
                until = end if until is None else max(until, end)
        return until if until is not None and until > now else None

    def _recheck(self, rkey: RKey) -> None:
        tx = self.live.get((rkey[0], rkey[1]))
        if tx is not None and tx.state == "deferred" and tx.rkey == rkey:
            self._start(tx, self.clock())

    def _send(self, tx: Transaction, now: float) -> None:
        if not self.pacer.ready(now):
            tx.state, tx.deadline = "paced", None
            self.pacer.hold(tx, now)
            return
        self._emit(tx, now)

    def _emit(self, tx: Transaction, now: float) -> None:
        self.pacer.sent(now)
        attempt = Attempt(tx, now)
        ledger = self._ledger.get(tx.rkey)
        if ledger is None:
            ledger = self._ledger[tx.rkey] = Ledger()
        ledger.prune(now - self.late_window_s)
        ledger.add(attempt)
        tx.attempts.append(attempt)
        if tx.first_sent_at is None:
            tx.first_sent_at = now
        tx.last_sent_at = now
        self._out.append(tx.frame)
        if not tx.expect_reply:
            tx.state, tx.deadline, tx.attempts = "done", None, []
            return
        tx.state = "sent"
        tx.deadline = now + tx.timeout_s

    def _finish(
        self, tx: Transaction, now: float, *, reply: Message | None = None, error: Exception | None = None
    ) -> None:
        tx.state, tx.reply, tx.error, tx.deadline = "done", reply, with_request(error, tx.frame), None
        tx.attempts = []  # the ledger still knows them; no cycle left for the garbage collector
        self._finished.append(tx)
        key = tx.key
        if self.live.get(key) is tx:
            del self.live[key]
            queue = self._waiting.get(key)
            if queue:
                nxt = queue.popleft()
                if not queue:
                    del self._waiting[key]
                self._start(nxt, now)


def with_request(error: Exception | None, frame: Frame) -> Exception | None:
    """`error` carrying the request it ended (`TopGimbalError.request`, as httpx's errors carry
    theirs): a copy, since one error may end many requests (a lost link, a closed client)."""
    if not isinstance(error, TopGimbalError) or error.request is frame:
        return error
    try:
        error = copy.copy(error)  # keeps the message and every attribute (a DecodeError's `answer`)
    except TypeError:  # an __init__ that copy cannot call again: this one error is the request's alone
        pass
    error.request = frame
    return error
