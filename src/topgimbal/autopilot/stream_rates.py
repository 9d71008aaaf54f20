"""What the autopilot can send on this link, learnt from what it sent (issue 42).

Staleness: a fixed limit is a guess about the link. PX4's onboard payload link in SITL runs at
4000 B/s; asked for SYSTEM_TIME at 1 Hz it sent one every 3.2-3.9 s, and a 3 s limit called the feed
stale and back four times a minute. So a message is stale once it is GAP_MARGIN times later than
the longest of its last GAPS_KEPT gaps (and never sooner than the message's own limit): a slow but
steady stream is not flapping, a stream that stopped still goes stale. Until a first gap is known
the limit is FIRST_GAP_FACTOR times the message's own (one message says nothing of the rate).

Answers: PX4's gimbal-mode link (MAV_n_MODE "Gimbal", mavlink_receiver.cpp
handle_messages_in_gimbal_mode) handles HEARTBEAT and the gimbal messages only: it never acks a
SET_MESSAGE_INTERVAL and streams neither GLOBAL_POSITION_INT, SYSTEM_TIME nor CAMERA_TRIGGER there.
`Answers` counts the requests the autopilot left unanswered so the bridge can say so once, and
ask more and more rarely rather than 14 times a minute."""

from __future__ import annotations

from collections import deque
from dataclasses import dataclass, field

GAPS_KEPT = 10
GAP_MARGIN = 2.0
FIRST_GAP_FACTOR = 3.0
UNANSWERED_BEFORE_SAYING = 3  # requests for one message without a single COMMAND_ACK before the bridge says why
MAX_RETRY_S = 60.0  # the longest wait between requests the autopilot does not answer


@dataclass
class Gaps:
    """Arrival gaps of one message from the autopilot."""

    last_s: float | None = None
    gaps_s: deque[float] = field(default_factory=lambda: deque(maxlen=GAPS_KEPT))

    def heard(self, now_s: float) -> None:
        if self.last_s is not None and now_s > self.last_s:
            self.gaps_s.append(now_s - self.last_s)
        self.last_s = now_s

    def stale_after_s(self, own_limit_s: float) -> float:
        """How long after the last message this one is stale on this link."""
        if not self.gaps_s:
            return own_limit_s * FIRST_GAP_FACTOR
        return max(own_limit_s, GAP_MARGIN * max(self.gaps_s))

    def period_s(self) -> float | None:
        """The mean gap of late: the rate the link carries (None before two messages)."""
        return sum(self.gaps_s) / len(self.gaps_s) if self.gaps_s else None


@dataclass
class Answers:
    """Whether the autopilot answers the bridge's requests on this link."""

    asked: int = 0  # the most times one message was asked for
    acked: int = 0
    said: bool = False

    def unanswered(self) -> bool:
        """True once UNANSWERED_BEFORE_SAYING requests went and no ack ever came."""
        return self.acked == 0 and self.asked >= UNANSWERED_BEFORE_SAYING

    def retry_s(self, base_s: float, times_asked: int) -> float:
        """Wait before asking again for a message asked `times_asked` times: `base_s` while the
        autopilot answers (or may yet), doubling with each unanswered request once it is clear it
        does not, up to MAX_RETRY_S."""
        if not self.unanswered():
            return base_s
        return min(MAX_RETRY_S, base_s * 2.0 ** max(1, times_asked - UNANSWERED_BEFORE_SAYING + 1))
