"""Asking the autopilot, on the bridge's own link, for what the photos need, as other MAVLink
peripherals do (issue 32): with ArduPilot's defaults nothing sends GLOBAL_POSITION_INT or
SYSTEM_TIME on a gimbal's serial port (MAVn_POSITION / MAVn_EXTRA3 are 0 there), so photos had no
position and were dated 1970.

Every CHECK_S, for each wanted message not heard from our vehicle's autopilot within its
staleness, the bridge sends MAV_CMD_SET_MESSAGE_INTERVAL (MAVLink's way; ArduPilot and PX4 apply it
to the link it came on) and REQUEST_DATA_STREAM for its stream group (what older firmware and
ArduPilot's SRn/MAVn_ rates answer), at most once per RETRY_S: bounded, and a log line each time.
It also says what the camera is fed: a line when a message is first heard, when it goes stale
(a warning) and when it comes back; `status()` gives the source and age of each, `feeds()` where
each of the camera's feeds (position, attitude, heading, time) comes from (feed_sources.py).

The autopilot is the system's component that sends AUTOPILOT_STATE_FOR_GIMBAL_DEVICE, or a
HEARTBEAT of a real autopilot (not MAV_AUTOPILOT_INVALID): nothing is asked of a ground station.

Staleness follows what the autopilot sends on this link (stream_rates.Gaps), not a fixed guess; an
autopilot that acks none of the requests (PX4's gimbal-mode link) is said so once, with what to do,
and asked more and more rarely (stream_rates.Answers)."""

from __future__ import annotations

import logging
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any, Protocol

from ..clock import MonotonicFn, monotonic
from ..links.mav import mav_id, mavlink, msg_id
from ..periodic import Periodic
from .feed_sources import WATCHED, FeedSources
from .stream_rates import Answers, Gaps

if TYPE_CHECKING:
    from ..links.mav import MAVLinkMessage


class Sender(Protocol):
    """Where the requests go: a component of the bridge (mavlink.node.Component), which sends as
    itself on every link; this package asks, the bridge owns the links."""

    def send(self, msg: MAVLinkMessage) -> None: ...


log = logging.getLogger("topgimbal.mavlink")

CHECK_S = 1.0
RETRY_S = 5.0  # a request unanswered is sent again no sooner than this
MAV_AUTOPILOT_INVALID = mav_id("MAV_AUTOPILOT_INVALID")
CMD_SET_MESSAGE_INTERVAL = mav_id("MAV_CMD_SET_MESSAGE_INTERVAL")
MAV_AUTOPILOT_PX4 = mav_id("MAV_AUTOPILOT_PX4")


@dataclass(frozen=True)
class Wanted:
    name: str
    msgid: int
    hz: float
    stream_id: int  # MAV_DATA_STREAM group that carries it (REQUEST_DATA_STREAM)
    what: str  # what it is for, for the log

    @property
    def stale_s(self) -> float:
        return max(2.0, 3.0 / self.hz)


WANTED = (
    Wanted(
        "GLOBAL_POSITION_INT",
        msg_id("GLOBAL_POSITION_INT"),
        10.0,
        mav_id("MAV_DATA_STREAM_POSITION"),
        "photo positions and the camera's position feed",
    ),
    Wanted(
        "SYSTEM_TIME",
        msg_id("SYSTEM_TIME"),
        1.0,
        mav_id("MAV_DATA_STREAM_EXTRA3"),
        "photo dates and the camera's clock",
    ),
)


class AutopilotStreams:
    # what on_message and its FeedSources read (node.on)
    MESSAGES: tuple[str, ...] = tuple(
        sorted({"HEARTBEAT", "AUTOPILOT_STATE_FOR_GIMBAL_DEVICE", "COMMAND_ACK", *(w.name for w in WANTED), *WATCHED})
    )

    def __init__(self, comp: Sender, sysid: int, own_compids: set[int], *, clock: MonotonicFn = monotonic) -> None:
        self.comp = comp
        self.sysid = sysid
        self.own = own_compids
        self.clock = clock
        self.autopilot_compid: int | None = None
        self.heard: dict[str, float] = {}  # message name -> when last heard from the autopilot
        self.asked: dict[str, float] = {}  # message name -> when last asked for
        self.times_asked: dict[str, int] = {}  # message name -> how many times asked for
        self.requests_sent = 0
        self.sources = FeedSources()  # what each of the camera's feeds comes from, for the operator
        self.gaps: dict[str, Gaps] = {w.name: Gaps() for w in WANTED}
        self.answers = Answers()
        self.autopilot_is_px4 = False
        self.gimbal_link = False  # the autopilot sends AUTOPILOT_STATE_FOR_GIMBAL_DEVICE here
        self._stale: set[str] = set()
        self._loop = Periodic(CHECK_S, self._check_now, name="asking the autopilot")

    def on_message(self, m: MAVLinkMessage) -> None:
        if m.get_srcSystem() != self.sysid or m.get_srcComponent() in self.own:
            return
        kind = m.get_type()
        self.sources.on_message(m, self.clock())
        if self.autopilot_compid is None and (
            kind == "AUTOPILOT_STATE_FOR_GIMBAL_DEVICE"
            or (kind == "HEARTBEAT" and m.autopilot != MAV_AUTOPILOT_INVALID)
        ):
            self.autopilot_compid = m.get_srcComponent()
            log.info("autopilot found: %d/%d", self.sysid, self.autopilot_compid)
        if m.get_srcComponent() == self.autopilot_compid:
            if kind == "HEARTBEAT":
                self.autopilot_is_px4 = m.autopilot == MAV_AUTOPILOT_PX4
            elif kind == "AUTOPILOT_STATE_FOR_GIMBAL_DEVICE":
                self.gimbal_link = True
            elif kind == "COMMAND_ACK" and m.command == CMD_SET_MESSAGE_INTERVAL:
                self.answers.acked += 1
        for w in WANTED:
            if kind == w.name:
                first = w.name not in self.heard
                self.heard[w.name] = self.clock()
                self.gaps[w.name].heard(self.heard[w.name])
                if first:
                    log.info("camera feed: %s from %d/%d (%s)", w.name, self.sysid, m.get_srcComponent(), w.what)
                elif w.name in self._stale:
                    self._stale.discard(w.name)
                    log.info("camera feed: %s from %d/%d again", w.name, self.sysid, m.get_srcComponent())

    def status(self) -> dict[str, Any]:
        """{message: {"source", "age_s" (None: never heard), "asked"}} for `info` and the log."""
        now = self.clock()
        src = f"{self.sysid}/{self.autopilot_compid}" if self.autopilot_compid is not None else None
        out: dict[str, Any] = {}
        for w in WANTED:
            heard = self.heard.get(w.name)
            out[w.name] = {
                "source": src,
                "age_s": None if heard is None else round(now - heard, 2),
                "stale": heard is None or now - heard > self.stale_after_s(w),
                "stale_after_s": round(self.stale_after_s(w), 2),
                "period_s": _round(self.gaps[w.name].period_s()),
                "asked": w.name in self.asked,
            }
        return out

    def feeds(self) -> dict[str, Any]:
        """Where each of the camera's feeds comes from now, or why it has none (feed_sources.py)."""
        src = f"{self.sysid}/{self.autopilot_compid}" if self.autopilot_compid is not None else None
        return self.sources.report(self.clock(), autopilot=src, asked=self.times_asked, asking=self._loop.started)

    def stale_after_s(self, w: Wanted) -> float:
        """How long after its last arrival `w` is stale: what this link showed it carries."""
        return self.gaps[w.name].stale_after_s(w.stale_s)

    def check(self) -> None:
        """Ask for what is missing; warn once when a message that came goes stale."""
        if self.autopilot_compid is None:
            return
        now = self.clock()
        for w in WANTED:
            heard = self.heard.get(w.name)
            limit_s = self.stale_after_s(w)
            if heard is not None and now - heard <= limit_s:
                continue
            if heard is not None and w.name not in self._stale:
                self._stale.add(w.name)
                log.warning("camera feed: no %s from the autopilot for %.1f s (this link carried one every "
                            "%s s at most): %s go stale", w.name, now - heard, _round(limit_s / 2), w.what)  # fmt: skip
            asked = self.asked.get(w.name)
            if asked is not None and now - asked < self.answers.retry_s(RETRY_S, self.times_asked.get(w.name, 0)):
                continue
            self.asked[w.name] = now
            self.times_asked[w.name] = self.times_asked.get(w.name, 0) + 1
            self._ask(w)

    def _ask(self, w: Wanted) -> None:
        ml = mavlink()
        target = (self.sysid, self.autopilot_compid or 1)
        interval_us = int(1e6 / w.hz)
        self.comp.send(ml.MAVLink_command_long_message(
            *target, CMD_SET_MESSAGE_INTERVAL, 0, w.msgid, interval_us, 0, 0, 0, 0, 0))  # fmt: skip
        self.comp.send(ml.MAVLink_request_data_stream_message(*target, w.stream_id, int(w.hz), 1))
        self.requests_sent += 1
        self.answers.asked = max(self.times_asked.values())  # rounds: each wanted message counts once
        if self.answers.unanswered() and not self.answers.said:
            self.answers.said = True
            log.warning("%s", self.why_unanswered())
        log.info("asking the autopilot %d/%d for %s at %g Hz on this link (SET_MESSAGE_INTERVAL, "
                 "REQUEST_DATA_STREAM %d): %s", *target, w.name, w.hz, w.stream_id, w.what)  # fmt: skip

    def why_unanswered(self) -> str:
        """What it means that the autopilot acks none of our requests, and what to do."""
        who = f"the autopilot {self.sysid}/{self.autopilot_compid}"
        if self.autopilot_is_px4 and self.gimbal_link:
            return (f"{who} (PX4) answered none of {self.answers.asked} requests on this link: it is PX4's "
                    "gimbal-mode link, which handles only HEARTBEAT and the gimbal messages and carries no "
                    "GLOBAL_POSITION_INT, SYSTEM_TIME or camera trigger: photos get no position or date and "
                    "PX4's triggers do not come here. Give the bridge a PX4 onboard link too (a second "
                    "--mavlink; docs/mavlink.md, PX4)")  # fmt: skip
        return (f"{who} answered none of {self.answers.asked} SET_MESSAGE_INTERVAL requests on this link: "
                "set its stream rates for this port (ArduPilot: SRn_/MAVn_ parameters) or give the bridge "
                "another link to it; asking less often from now on")  # fmt: skip

    def start(self) -> None:
        self._loop.start()

    async def close(self) -> None:
        await self._loop.close()

    async def _check_now(self) -> None:
        self.check()


def _round(x: float | None) -> float | None:
    return None if x is None else round(x, 2)
