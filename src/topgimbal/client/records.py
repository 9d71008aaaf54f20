"""What the transaction engine keeps: requests (`Transaction`), their sends (`Attempt`), the
attempts on one key (`Ledger`), and what it made of a frame (`Inbound`). Plain data; the rules are
in engine.py."""

from __future__ import annotations

import contextlib
import itertools
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from typing import Any

from ..protocol import Frame, Message

Key = tuple[str, str]  # (identifier, device address): one live request at a time
RKey = tuple[str, str, str]  # (identifier, device address, control): where its answers land
Clock = Callable[[], float]
EchoRule = Callable[[Frame, "Mapping[str, Any] | None", Message], bool]

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
        if self.open and self.open[0].sent_at < window:
            self.open = [a for a in self.open if a.sent_at >= window]
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
    fields: Mapping[str, Any] | None = None  # the request's values as on the wire (ack rules)
    submitted_at: float = 0.0
    id: int = field(default_factory=lambda: next(_ids))
    state: str = "queued"  # queued -> deferred -> sent -> done
    attempts: list[Attempt] = field(default_factory=list)
    first_sent_at: float | None = None
    last_sent_at: float | None = None
    deadline: float | None = None
    reply: Message | None = None
    error: Exception | None = None
    notes: list[str] = field(default_factory=list)
    waiter: Any = None

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
    ambiguous, mismatch, error, unsolicited, ignored. `tx` is the request it finished."""

    kind: str
    tx: Transaction | None = None

    @property
    def dispatch(self) -> bool:
        """Whether subscribers and the state cache should see the frame."""
        return self.kind not in ("duplicate", "ignored")
