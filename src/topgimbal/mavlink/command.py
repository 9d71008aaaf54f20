"""A MAVLink command as the bridge's handlers see it (`Command`: COMMAND_LONG or COMMAND_INT, its
parameters checked by name: `whole`, `finite`), what a handler returns (`Outcome`) or raises
(`denied`, `unsupported`, `rejected`), and the MAVLink results (pure: no I/O, no clock).
commands.py's Dispatcher turns these into the one true COMMAND_ACK."""

from __future__ import annotations

import math
from collections.abc import Awaitable, Callable
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any

from ..errors import TopGimbalError
from ..links.base import link_peer

if TYPE_CHECKING:
    from ..links.mav import MAVLinkMessage

ACCEPTED, TEMPORARILY_REJECTED, DENIED, UNSUPPORTED, FAILED, IN_PROGRESS, CANCELLED = 0, 1, 2, 3, 4, 5, 6
RESULT_NAMES = {
    0: "accepted",
    1: "temporarily rejected",
    2: "denied",
    3: "unsupported",
    4: "failed",
    5: "in progress",
    6: "cancelled",
}
# result_param2 on FAILED: why the camera did not confirm (documented in docs/mavlink.md).
CAMERA_ERROR, CAMERA_TIMEOUT, CAMERA_LINK_DOWN, BRIDGE_ERROR, CAMERA_WRONG_MODEL = 1, 2, 3, 4, 5


class CommandRefusedError(TopGimbalError):
    """A handler's own refusal, with the MAVLink result to send."""

    def __init__(self, result: int, text: str) -> None:
        super().__init__(text)
        self.result = result


def denied(text: str) -> CommandRefusedError:
    return CommandRefusedError(DENIED, text)


def unsupported(text: str) -> CommandRefusedError:
    return CommandRefusedError(UNSUPPORTED, text)


def rejected(text: str) -> CommandRefusedError:
    return CommandRefusedError(TEMPORARILY_REJECTED, text)


@dataclass(frozen=True)
class Command:
    command: int
    params: tuple[float, float, float, float, float, float, float]
    src_system: int
    src_component: int
    target_system: int
    target_component: int
    confirmation: int = 0
    is_int: bool = False
    frame: int = 0
    # Where the command came from on the link (node.link_peer); not part of its identity.
    peer: Any = field(default=None, compare=False)

    def p(self, n: int) -> float:
        return self.params[n - 1]

    def has(self, n: int) -> bool:
        return not math.isnan(self.params[n - 1])

    def whole(self, n: int, what: str, lo: int, hi: int, default: int | None = None) -> int:
        """Parameter n as a whole number lo..hi (NaN gives `default` where the command allows
        leaving it out); anything else (inf, a fraction, out of range) is refused with DENIED
        naming the parameter, before any work starts."""
        v = self.params[n - 1]
        if math.isnan(v) and default is not None:
            return default
        if not math.isfinite(v) or v != int(v) or not lo <= v <= hi:
            raise CommandRefusedError(DENIED, f"param{n} ({what}) {v:g}: expected a whole number {lo}..{hi}")
        return int(v)

    def finite(self, n: int, what: str) -> float:
        """Parameter n, refused with DENIED when it is NaN or infinite."""
        v = self.params[n - 1]
        if not math.isfinite(v):
            raise CommandRefusedError(DENIED, f"param{n} ({what}) {v:g}: expected a finite number")
        return v

    @property
    def lat_deg(self) -> float:
        return self.params[4] / 1e7 if self.is_int else self.params[4]

    @property
    def lon_deg(self) -> float:
        return self.params[5] / 1e7 if self.is_int else self.params[5]

    def key(self) -> tuple[Any, ...]:
        # NaN ("not given") is common in parameters and never equal to itself, and in Python 3.10+
        # two NaN floats hash apart: a retransmission would never match its first copy and would
        # act again. Every NaN counts as the same "not given".
        # The message type is part of it: a COMMAND_INT is never a retransmission of a
        # COMMAND_LONG (a sender retransmits with the same message), and their parameters 5 and 6
        # mean different things (scaled integers vs floats).
        params = tuple(None if math.isnan(v) else v for v in self.params)
        kind = "INT" if self.is_int else "LONG"
        return (self.src_system, self.src_component, self.target_component, kind, self.command, params, self.frame)

    def retransmits(self, earlier_confirmation: int) -> bool:
        """Whether this copy, arriving after an identical one (same key) that ended within the
        retransmission window, is that command sent again rather than a new order. MAVLink's
        command protocol: COMMAND_LONG `confirmation` is 0 on the first transmission and counts
        up on each retransmission, so 0 is always a new command and a retransmission carries a
        higher number than the copy we answered (an equal one is the same frame duplicated on
        the way, e.g. by a router on two links). COMMAND_INT has no such field: senders (QGC,
        MAVSDK) repeat it unchanged, so an identical one within the window is a retransmission."""
        if self.is_int:
            return True
        return self.confirmation > 0 and self.confirmation >= earlier_confirmation

    @classmethod
    def from_message(cls, m: MAVLinkMessage) -> Command:
        if m.get_type() == "COMMAND_INT":
            params = (m.param1, m.param2, m.param3, m.param4, float(m.x), float(m.y), m.z)
            return cls(m.command, params, m.get_srcSystem(), m.get_srcComponent(), m.target_system,
                       m.target_component, 0, True, m.frame, link_peer(m))  # fmt: skip
        params = (m.param1, m.param2, m.param3, m.param4, m.param5, m.param6, m.param7)
        return cls(m.command, params, m.get_srcSystem(), m.get_srcComponent(), m.target_system,
                   m.target_component, m.confirmation, peer=link_peer(m))  # fmt: skip


@dataclass
class Outcome:
    """What a handler may return besides None (= ACCEPTED): a result and messages to send after
    the ack (the answer to MAV_CMD_REQUEST_MESSAGE follows its ack)."""

    result: int = ACCEPTED
    param2: int = 0
    after: list[Any] = field(default_factory=list)
    text: str = ""
    logged: bool = False  # the dispatcher's log already said why (its own line is left out)


Handler = Callable[[Command], Awaitable["Outcome | None"]]
Accepts = Callable[[Command], bool]
