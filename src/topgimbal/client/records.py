"""What the transaction engine keeps: requests (`Transaction`), their sends (`Attempt`), the
attempts on one key (`Ledger`), the frames waiting for their turn (`Pacer`), and what it made of a
frame (`Inbound`). Plain data; the rules are in engine.py."""

from __future__ import annotations

import contextlib
import itertools
import math
from collections import deque
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from typing import TYPE_CHECKING

from ..protocol import Frame, Message

if TYPE_CHECKING:
    from asyncio import Future

Key = tuple[str, str]  # (identifier, device address): one live request at a time
RKey = tuple[str, str, str]  # (identifier, device address, control): where its answers land
Clock = Callable[[], float]
EchoRule = Callable[[Frame, "Mapping[str, object] | None", Message], bool]

MAX_LEDGER = 1024  # attempts remembered per key (only an absurd send rate reaches it)

_ids = itertools.count(1)


@dataclass(eq=False)
class Attempt:
    tx: Transaction
    sent_at: float
    closed: bool = False  # a frame was taken as its answer


class Ledger:
    """The attempts on one key within the late window: the open ones in send order, and the last
    answered one per request data (copies of its answer may still come)."""

    __slots__ = ("answered", "open")

    def __init__(self) -> None:
        self.open: list[Attempt] = []
        self.answered: dict[bytes, Attempt] = {}

    def prune(self, window: float) -> None:
        """Forget the open attempts sent before `window`, except those of a request still waiting
        for its answer: a process that stood still past the late window (a loaded host) reads the
        answer before its timers run, and with its own attempt forgotten, a write's echo that
        carried the data sent was reported as carrying other data."""
        if self.open and self.open[0].sent_at < window:
            self.open = [a for a in self.open if a.sent_at >= window or a.tx.state == "sent"]
        if len(self.answered) > 32:
            self.answered = {k: a for k, a in self.answered.items() if a.sent_at >= window}

    def add(self, attempt: Attempt) -> None:
        if len(self.open) >= MAX_LEDGER:
            del self.open[0]
        self.open.append(attempt)

    def close(self, attempt: Attempt) -> None:
        attempt.closed = True
        with contextlib.suppress(ValueError):
            self.open.remove(attempt)
        self.answered[attempt.tx.frame.data] = attempt


@dataclass(eq=False)
class Transaction:
    """One request. `waiter` is a slot for the I/O layer (an asyncio future)."""

    frame: Frame
    timeout_s: float
    retries: int
    expect_reply: bool = True
    exclusive: bool = False  # non-idempotent: sent once, on a quiet key
    fields: Mapping[str, object] | None = None  # the request's values as on the wire (ack rules)
    submitted_at: float = 0.0
    slow: bool = False  # a constant the device may answer very late: never deferred or retried
    lenient: bool = False  # taken even with a recovered length character (known firmware errors)
    background: bool = False  # a periodic feed frame: a paced queue lets every other frame pass it
    held_at: float = 0.0  # when it (or the frame it replaced) took its place in the paced queue
    # a frame came too soon after it to be its answer: how many attempts it had then (0: none)
    suspected_copy: int = 0
    id: int = field(default_factory=lambda: next(_ids))
    state: str = "queued"  # queued -> deferred -> paced -> sent -> done
    # Sends of a live request (emptied when it is done: each Attempt points back at its request,
    # and a request that kept its attempts would be a reference cycle, freed only by the garbage
    # collector, whose pauses were the client's p99)
    attempts: list[Attempt] = field(default_factory=list)
    first_sent_at: float | None = None
    last_sent_at: float | None = None
    deadline: float | None = None
    reply: Message | None = None
    error: Exception | None = None
    notes: list[str] = field(default_factory=list)
    waiter: Future[Message | None] | None = None  # the I/O layer's slot

    @property
    def key(self) -> Key:
        return (self.frame.ident, self.frame.dst)

    @property
    def rkey(self) -> RKey:
        return (self.frame.ident, self.frame.dst, self.frame.rw or "w")

    @property
    def done(self) -> bool:
        return self.state == "done"

    @property
    def waited_s(self) -> float:
        """Time between submit and first send (queue and deferral)."""
        start = self.first_sent_at if self.first_sent_at is not None else self.submitted_at
        return max(0.0, start - self.submitted_at)


@dataclass(frozen=True)
class Inbound:
    """What the engine made of one frame from the device. `kind`: answer, late, duplicate,
    ambiguous, mismatch, error, unsolicited, unawaited (the echo of a frame sent without waiting),
    ignored. `tx` is the request it finished."""

    kind: str
    tx: Transaction | None = None

    @property
    def dispatch(self) -> bool:
        """Whether subscribers and the state cache should see the frame."""
        return self.kind not in ("duplicate", "ignored")


# What a frame that finished no request is, made once: Inbound is frozen, so one object serves every
# such frame (one allocation fewer per stream sample, the commonest frame of all).
UNSOLICITED, LATE, IGNORED, DUPLICATE, AMBIGUOUS, UNAWAITED, NO_TX_ERROR = (
    Inbound(k) for k in ("unsolicited", "late", "ignored", "duplicate", "ambiguous", "unawaited", "error")
)


PACE_SLACK_S = 1e-6  # timers may fire a hair early; a microsecond is no pacing error
# A background frame lets others pass for this long at most (Pacer): two periods of the C12's
# 10 Hz vehicle attitude feed, five of its 40 ms turns.
BACKGROUND_MAX_WAIT_S = 0.2


class Pacer:
    """Frames out no closer together than `gap_s` (a model's `min_command_gap_s`), first come
    first served, except that a background frame (a periodic feed: position, time, the vehicle's
    attitude) lets every other frame pass it: a photo request behind a queue of feeds waited up to
    0.2 s more on the C12's 40 ms pacing, 1.8 m of a survey's spacing at 9 m/s (issue 42). With no
    gap, everything goes at once. A frame sent without waiting for an answer replaces one still
    waiting on its key with other data (a newer set-point supersedes it: a joystick or a pointing
    loop never builds a backlog); identical ones are kept (repeats), and a replacement keeps the
    place's waiting time.

    Letting others pass is bounded: a background frame that has waited BACKGROUND_MAX_WAIT_S goes
    next, but never two such in a row (a frame that waits goes between them). A pointing loop
    that sends its next set-point as soon as the last is confirmed keeps a frame waiting at every
    turn; the feeds then never went: under ArduPilot SITL the C12 was told a vehicle attitude 10 s
    old or more, and its stabilised pitch was off by the vehicle's tilt since (1.1-1.7 deg)."""

    __slots__ = ("aged_last", "gap_s", "next_at", "queue")

    def __init__(self, gap_s: float = 0.0) -> None:
        self.gap_s = gap_s
        self.next_at = -math.inf
        self.queue: deque[Transaction] = deque()
        self.aged_last = False  # the last frame out was a background frame that had waited its most

    def ready(self, now: float) -> bool:
        return not self.gap_s or (not self.queue and now >= self.next_at - PACE_SLACK_S)

    def hold(self, tx: Transaction, now: float) -> None:
        tx.held_at = now
        if not tx.expect_reply:
            for i in range(len(self.queue) - 1, -1, -1):  # the latest one on its key
                old = self.queue[i]
                if old.key == tx.key:
                    if not old.expect_reply and old.frame.data != tx.frame.data:
                        old.state = "done"  # superseded: never sent
                        tx.held_at = old.held_at  # its place, and how long that place has waited
                        self.queue[i] = tx
                        return
                    break
        self.queue.append(tx)

    def sent(self, now: float) -> None:
        if self.gap_s:
            self.next_at = now + self.gap_s

    def due(self, now: float) -> Transaction | None:
        """The next held request whose turn has come (requests given up meanwhile are dropped):
        the first that is not a background frame, else the first background one; but the first
        background frame once it has waited BACKGROUND_MAX_WAIT_S, unless the last one out went
        for that reason too (the class docstring)."""
        queue = self.queue
        while queue and now >= self.next_at - PACE_SLACK_S:
            head = queue[0]  # background frames keep their order: the first is the longest waiting
            if head.background and (self.aged_last or now - head.held_at < BACKGROUND_MAX_WAIT_S):
                for i, tx in enumerate(queue):
                    if not tx.background:
                        del queue[i]
                        if tx.state == "paced":
                            self.aged_last = False
                            return tx
                        break
                else:
                    tx = queue.popleft()
                    if tx.state == "paced":
                        self.aged_last = False  # nothing else waited: it was not let pass
                        return tx
                continue
            tx = queue.popleft()
            if tx.state == "paced":
                self.aged_last = tx.background
                return tx
        return None

    def next_deadline(self) -> float | None:
        return self.next_at if self.queue else None

    def clear(self) -> None:
        for tx in self.queue:
            if not tx.expect_reply:
                tx.state = "done"
        self.queue.clear()

    def drop_unsent(self, idents: frozenset[str]) -> int:
        """Frames sent without waiting for an answer, held for their turn, of these identifiers:
        never sent (the client stopped what sends them: a device of another model). How many."""
        dropped = 0
        for tx in self.queue:
            if not tx.expect_reply and tx.state == "paced" and tx.frame.ident in idents:
                tx.state = "done"
                dropped += 1
        return dropped


def timeout_text(tx: Transaction, now: float) -> str:
    """Why a request failed for want of an answer, with the true elapsed times."""
    n = len(tx.attempts)
    sent_for = now - (tx.first_sent_at or now)
    text = (
        f"no reply to {tx.frame.ident} ({tx.frame.text()}) after {n} attempt{'s' if n != 1 else ''} in {sent_for:.2f} s"
    )
    if tx.waited_s >= 0.01:
        text += (
            f" ({now - tx.submitted_at:.2f} s in all: it first waited {tx.waited_s:.2f} s for earlier "
            f"requests on {tx.frame.ident} to be answered or run out)"
        )
    if tx.exclusive:
        text += f"; {tx.frame.ident} acts on every copy, so it is never retried"
    if tx.slow:
        text += f"; this model may answer {tx.frame.ident} very late or never (its answer still reaches cam.state)"
    if tx.notes:
        text += "; " + "; ".join(dict.fromkeys(tx.notes))
    return text
