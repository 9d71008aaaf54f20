"""Which request a frame from the device answers: the incoming half of the transaction engine
(engine.py, whose module docstring gives the rules; docs/client.md, "Matching"). A part of `Engine`
(it inherits this), kept apart for its size: the state it reads is declared below and set by
`Engine.__init__`. No I/O; the engine's injected clock."""

from __future__ import annotations

from ..errors import DeviceError
from ..protocol import Message
from .acks import is_report
from .records import (
    AMBIGUOUS,
    DUPLICATE,
    IGNORED,
    LATE,
    NO_TX_ERROR,
    UNAWAITED,
    UNSOLICITED,
    Attempt,
    Clock,
    EchoRule,
    Inbound,
    Key,
    Ledger,
    RKey,
    Transaction,
)
from .stats import LinkStats

# A copy of an answer comes right behind the original: one arriving within this long after a query
# went out (and sooner than half the fastest round trip seen) cannot be that query's answer. Capped
# so that a slow first round trip cannot make later fast answers look like copies.
COPY_FLOOR_CAP_S = 0.0002
SETTLED_RTT_SAMPLES = 16  # round trips seen before half the fastest one bounds how fast an answer can be


class Matching:
    # Slots (with Engine's): one engine per client, read per frame; a fleet server's 1,000 should
    # stay in cache. The annotations below are the slots' types.
    __slots__ = ("_last_error", "_last_frame", "_ledger", "_rtt_samples", "_streams", "clock", "copies_seen",
                 "dup_window_s", "echo_matches", "late_window_s", "live", "recovered_ok", "stats")  # fmt: skip
    # the engine's state (engine.py)
    clock: Clock
    late_window_s: float
    dup_window_s: float
    stats: LinkStats
    echo_matches: EchoRule
    recovered_ok: frozenset[str]
    live: dict[Key, Transaction]
    copies_seen: bool
    _ledger: dict[RKey, Ledger]
    _last_frame: dict[RKey, tuple[float, bytes]]
    _last_error: dict[str, float]
    _rtt_samples: int
    _streams: dict[str, float]

    def _streaming(self, ident: str, now: float) -> bool:
        raise NotImplementedError  # Engine's

    def _finish(
        self, tx: Transaction, now: float, *, reply: Message | None = None, error: Exception | None = None
    ) -> None:
        raise NotImplementedError  # Engine's

    def _close(self, attempt: Attempt) -> None:
        raise NotImplementedError  # Engine's

    def _recheck(self, rkey: RKey) -> None:
        raise NotImplementedError  # Engine's

    # -- incoming ---------------------------------------------------------------------------------

    def on_message(self, message: Message, now: float | None = None) -> Inbound:
        """Classify one decoded frame from the device; completes at most one request. `now`: the
        engine's clock read by the caller (one read per datagram on the per-sample path)."""
        frame = message.frame
        if now is None:
            now = self.clock()
        if message.is_error:
            return self._on_error(message, now)
        rkey = (frame.ident, frame.src, frame.rw or "w")
        if frame.declared_length is not None and frame.ident not in self.recovered_ok:
            lenient = self.live.get((frame.ident, frame.src))
            if lenient is None or not lenient.lenient:
                self.stats.bad_frames += 1
                return IGNORED
        last = self._last_frame.get(rkey)
        self._last_frame[rkey] = (now, frame.data)
        if self._streams and frame.rw == "r" and self._streaming(frame.ident, now):
            return self._on_sample(message, rkey, now)
        # Right behind an identical frame: perhaps a network copy, so it proves no other attempt answered.
        maybe_copy = last is not None and last[1] == frame.data and now - last[0] <= self.dup_window_s
        ledger = self._ledger.get(rkey)
        live = self.live.get((frame.ident, frame.src))
        if live is not None and (live.state != "sent" or live.rkey != rkey):
            live = None
        if ledger is None:
            return self._unowned(message, live, now, known=False)
        window = now - self.late_window_s
        ledger.prune(window)
        if frame.rw == "r":
            if is_report(message):
                return UNSOLICITED  # a stream frame on a query's key
            fits = list(ledger.open)
        else:
            fits = [a for a in ledger.open if self.echo_matches(a.tx.frame, a.tx.fields, message)]
        own = [a for a in fits if a.tx is live]
        foreign = [a for a in fits if a.tx is not live]
        if (
            live is not None
            and own
            and frame.rw == "r"
            and live.first_sent_at is not None
            and maybe_copy
            and now < live.first_sent_at + self._copy_floor_s()
        ):
            # An identical frame sooner than any answer can come: a copy of the previous one.
            # The link is taken to copy frames only once another frame follows for this
            # request: a real answer that was just unusually fast (loopback under load) costs
            # this request a retry, not every later read the copy wait.
            self.stats.duplicates += 1
            live.suspected_copy = len(live.attempts)
            return DUPLICATE
        if live is not None and own and (not foreign or frame.rw == "w" or live.slow):
            # Reads never have foreign attempts here (deferred until there are none); a write's
            # echo with the data sent proves the data were applied, whichever attempt it answers.
            return self._answer(live, own, message, now, sole=not foreign)
        if foreign:
            if live is not None and own:
                self.stats.ambiguous += 1
                live.notes.append(f"{frame.text()} could answer this request or an earlier one: not taken")
                return AMBIGUOUS
            if not maybe_copy:
                self._close_if_single_owner(foreign)
            if all(not a.tx.expect_reply for a in foreign):
                return UNAWAITED  # the echo of a frame sent without waiting: not late
            self.stats.late_replies += 1
            return LATE
        # Fits an attempt that was answered already: another copy of that answer.
        known = any(
            a.sent_at >= window and (frame.rw == "r" or self.echo_matches(a.tx.frame, a.tx.fields, message))
            for a in ledger.answered.values()
        )
        return self._unowned(message, live, now, known=known)

    def _on_sample(self, message: Message, rkey: RKey, now: float) -> Inbound:
        """A frame on a streaming key: a sample, and the live read's answer once that read is
        sent (any sample after the query carries a value the device held since; samples and
        answers look alike, so every open attempt there is answered alike)."""
        live = self.live.get((rkey[0], rkey[1]))
        if live is None or live.state != "sent" or live.rkey != rkey:
            return UNSOLICITED
        ledger = self._ledger.get(rkey)
        if ledger is None or is_report(message) or not any(a.tx is live for a in ledger.open):
            return UNSOLICITED
        for attempt in list(ledger.open):
            ledger.close(attempt)
        self.stats.replies += 1  # no round trip: a sample may have left before the query came
        self._finish(live, now, reply=message)
        return Inbound("answer", live)

    def _unowned(self, message: Message, live: Transaction | None, now: float, *, known: bool) -> Inbound:
        """A frame that fits no open attempt: a report, a copy of an answer already taken, a
        mismatched echo, or a stray answer."""
        if is_report(message):
            return UNSOLICITED
        if known:
            self._copy_seen()
            return LATE
        if live is not None and message.frame.rw == "w":
            # An echo with other data than any attempt sent: the device did something else.
            self.stats.errors += 1
            err = DeviceError(
                f"the device acknowledged {live.frame.ident} ({live.frame.text()}) with {message.frame.text()}, "
                f"which does not carry the data sent; the setting may not be what was asked"
            )
            self._finish(live, now, error=err)
            return Inbound("mismatch", live)
        ledger = self._ledger.get((message.frame.ident, message.frame.src, message.frame.rw or "w"))
        if ledger is not None and (ledger.open or ledger.answered):
            self.stats.stray_replies += 1
            return LATE
        return UNSOLICITED

    def _copy_floor_s(self) -> float:
        """How soon after a query an identical frame must be a copy: half the fastest round trip
        seen (a quarter while fewer than SETTLED_RTT_SAMPLES were seen: the first ones are slow,
        and a floor too high takes fast real answers for copies), at most COPY_FLOOR_CAP_S."""
        rtt_min = self.stats.rtt_ms_min
        if rtt_min is None:
            return COPY_FLOOR_CAP_S
        share = 0.5 if self._rtt_samples >= SETTLED_RTT_SAMPLES else 0.25
        return min(share * rtt_min / 1000.0, COPY_FLOOR_CAP_S)

    def _copy_seen(self) -> None:
        self.stats.duplicates += 1
        self.copies_seen = True

    def _answer(self, tx: Transaction, own: list[Attempt], message: Message, now: float, *, sole: bool) -> Inbound:
        oldest = own[0]
        self._close(oldest)
        if sole and len(own) == 1:
            self.stats.add_rtt(now - oldest.sent_at)  # only when it is clear which attempt answered
            self._rtt_samples += 1
        if tx.suspected_copy and tx.suspected_copy == len(tx.attempts):
            self.copies_seen = True  # another frame followed the suspected copy, before any retry
        self.stats.replies += 1
        self._finish(tx, now, reply=message)
        return Inbound("answer", tx)

    def _close_if_single_owner(self, attempts: list[Attempt]) -> None:
        owner = attempts[0].tx
        if all(a.tx is owner for a in attempts):
            self._close(attempts[0])
            self._recheck(attempts[0].tx.rkey)

    def _on_error(self, message: Message, now: float) -> Inbound:
        self.stats.errors += 1
        src = message.frame.src
        previous = self._last_error.get(src)
        self._last_error[src] = now
        window = now - self.late_window_s
        owners = {
            a.tx for rkey, ledger in self._ledger.items() if rkey[1] == src for a in ledger.open if a.sent_at >= window
        }
        live = [t for t in owners if t.state == "sent" and self.live.get(t.key) is t]
        copy = previous is not None and now - previous <= self.dup_window_s  # may copy the last one
        if len(owners) == 1 and len(live) == 1 and not copy:
            tx = live[0]
            self._close(next(a for a in tx.attempts if not a.closed))
            err = DeviceError(
                f"the device refused {tx.frame.ident} ({tx.frame.text()}): it answered {message.frame.text()}"
            )
            self._finish(tx, now, error=err)
            return Inbound("error", tx)
        for tx in live:
            tx.notes.append(
                f"the device sent an error frame {message.frame.text()} that may answer this request or another to {src}"
            )
        return NO_TX_ERROR
