"""The bridge feeds the camera what the autopilot says, so its photos carry where and when they
were taken: the position (GLOBAL_POSITION_INT), the vehicle attitude (AUTOPILOT_STATE_FOR_GIMBAL_DEVICE,
else ATTITUDE: `Vehicles.attitude_deg()`) and the UTC time (SYSTEM_TIME, handled here).

Every `PERIOD_S` the latest of each goes to the client's feeds (client/feeds.py), which send them at
the model's profile rates (TOPOTEK: LAT, LON, ALT, AZI at 10 Hz and UTC at 1 Hz, as ArduPilot's
AP_Mount_Topotek does; C12: FAI 10 Hz, LAT/LON/ALT 2 Hz, TIM 1 Hz).

No fix, no feed: a GLOBAL_POSITION_INT older than vehicle.STALE_S, or at 0, 0 (what an autopilot
sends before its first fix), stops the position feeds; the camera keeps the last position it
was given, as a real one does, but nothing stale is sent as if it were current. SYSTEM_TIME with
time_unix_usec 0 (no GPS time yet) is ignored: the camera's clock is then left alone (a camera
without a clock keeps counting from 1970, the others keep theirs)."""

from __future__ import annotations

import dataclasses
import datetime
import logging
from collections.abc import Mapping
from typing import TYPE_CHECKING, Any

from ..autopilot.vehicle import TIME_STALE_S
from ..client.api_feed import FeedSample, apply_sample
from ..client.feeds import FedPosition
from ..clock import monotonic
from ..errors import TopGimbalError
from ..periodic import Periodic
from ..protocol import get_model
from ..protocol.streams import photo_names

if TYPE_CHECKING:
    from ..autopilot.vehicle import Vehicles
    from ..links.mav import MAVLinkMessage
    from .camera_link import CameraLink

log = logging.getLogger("topgimbal.mavlink")

PERIOD_S = 0.1
SHUTTER_LATENCY_S = 0.005  # the camera's answer after a photo request on a LAN, besides the pacing
MAX_SHUTTER_LEAD_S = 1.0  # the pushed position is held for a photo at most this long


def file_url(media_url: str | None, model: str, lens: str, answer: Mapping[str, object] | None) -> str:
    """CAMERA_IMAGE_CAPTURED.file_url: the photo's file on the camera's media server, where the
    bridge was told that server (`--media-url`) and the camera's answer names the file (TOPOTEK's
    CAP feedback carries its file index); else empty, as MAVLink allows."""
    index = (answer or {}).get("file_index")
    if not media_url or not isinstance(index, int):
        return ""
    return media_url.rstrip("/") + "/" + photo_names(get_model(model)[0].name, index, [lens])[lens]


class AutopilotState:
    """What the autopilot says, as a FeedSample: the fix and attitude from `Vehicles`, the time
    from SYSTEM_TIME (handled here)."""

    MESSAGES: tuple[str, ...] = ("SYSTEM_TIME",)  # what on_message reads (node.on)

    def __init__(self, vehicles: Vehicles, sysid: int, own_compids: set[int]) -> None:
        self.vehicles = vehicles
        self.sysid = sysid
        self.own = own_compids
        self._utc: tuple[datetime.datetime, float] | None = None  # (autopilot UTC, monotonic when heard)
        self.utc_new = False  # a SYSTEM_TIME not yet handed on

    def on_message(self, m: MAVLinkMessage) -> None:
        if m.get_type() != "SYSTEM_TIME" or m.get_srcSystem() != self.sysid or m.get_srcComponent() in self.own:
            return
        usec = int(m.time_unix_usec)
        if usec <= 0:
            return  # no GPS time yet
        try:
            utc = datetime.datetime.fromtimestamp(usec / 1e6, datetime.timezone.utc)
        except (OverflowError, OSError, ValueError):
            return  # a time no calendar holds: not a time
        self._utc, self.utc_new = (utc, monotonic()), True

    @property
    def has_time(self) -> bool:
        return self._utc is not None

    def utc_at(self, t: float) -> float | None:
        """The autopilot's UTC (seconds since the epoch) at `t` on this clock, from the last
        SYSTEM_TIME and the time since it was heard; None when none was (GPS time unknown)."""
        if self._utc is None:
            return None
        utc, heard = self._utc
        return utc.timestamp() + (t - heard)

    def time_age_s(self) -> float | None:
        return None if self._utc is None else monotonic() - self._utc[1]

    def fix_at(self, t: float) -> FedPosition | None:
        """The vehicle's position at `t` (vehicle.Vehicles.position_at) as the camera's feeds take it:
        None without one, at 0, 0 (an autopilot before its first fix) or out of range (numbers from
        the network)."""
        f = self.vehicles.position_at(t)
        if f is None or (f.position.lat_deg == 0 and f.position.lon_deg == 0):
            return None
        try:
            return FedPosition(f.position.lat_deg, f.position.lon_deg, f.position.alt_m, self.vehicles.yaw_deg)
        except ValueError:
            return None

    def sample(self) -> FeedSample:
        """What the autopilot says now (a fix only when it is fresh and not 0, 0)."""
        fix = self.fix_at(monotonic())  # carried forward to now at its velocity
        utc = None
        if self._utc is not None and self.utc_new and monotonic() - self._utc[1] <= TIME_STALE_S:
            utc = self._utc[0] + datetime.timedelta(seconds=monotonic() - self._utc[1])
        return FeedSample(fix=fix, time_utc=utc, attitude_deg=self.vehicles.attitude_deg())


class MavlinkSource:
    """A feed source for `cam.feed_from(...)` reading an autopilot's MAVLink connection without the
    bridge: anything with pymavlink's `recv_match(blocking=False)` (e.g.
    `mavutil.mavlink_connection("udpin:127.0.0.1:14551")`). Each call drains at most
    `max_messages` and returns what the autopilot says now."""

    def __init__(self, conn: Any, sysid: int = 1, *, max_messages: int = 500) -> None:
        from ..autopilot.vehicle import Vehicles

        self.conn = conn
        self.max_messages = max_messages
        self.state = AutopilotState(Vehicles(sysid, set()), sysid, set())

    def __call__(self) -> FeedSample:
        for _ in range(self.max_messages):
            m = self.conn.recv_match(blocking=False)
            if m is None:
                break
            if m.get_type() == "BAD_DATA":
                continue
            self.state.vehicles.on_message(m)
            self.state.on_message(m)
        sample = self.state.sample()
        self.state.utc_new = False
        return sample


class CameraFeed:
    def __init__(self, cam: CameraLink, vehicles: Vehicles, sysid: int, own_compids: set[int]) -> None:
        self.cam = cam
        self.autopilot = AutopilotState(vehicles, sysid, own_compids)
        self.on_message = self.autopilot.on_message
        self.MESSAGES = self.autopilot.MESSAGES
        self._client: object = None  # the client last fed (a reconnect makes a new one: time again)
        self._loop = Periodic(PERIOD_S, self._feed_once, name="camera feed")
        self.samples = 0
        self.state = "waiting for the autopilot"
        self._photo_asked: float | None = None  # when a position was pushed for a photo not yet taken

    def sample(self) -> FeedSample:
        return self.autopilot.sample()

    def before_photo(self) -> None:
        """Right before a photo request: the camera is sent the vehicle's position predicted at
        its shutter, at once, rather than waiting for the next position feed period (the camera
        tags the photo with the last position it was given). The shutter comes after these frames
        and the photo request, each paced by the model's least command gap. (Learning the delay
        from the photos before did worse: it varies by +-35 ms with the other feeds' frames.)"""
        self._photo_asked = None
        client = self.cam.client
        if client is None or not client.connected:
            return
        feeds = client.feeds
        idents = feeds.active_position_feeds()
        if not idents:
            return
        now = monotonic()
        lead_s = (len(idents) + 1) * client.behaviour.min_gap_s + SHUTTER_LATENCY_S
        fix = self.autopilot.fix_at(now + lead_s)
        if fix is None:
            return
        feeds.position(fix)
        feeds.send_now()
        self._photo_asked = now

    def photo_taken(self, shutter: float) -> None:
        """The photo `before_photo` prepared was taken: the periodic feed goes on."""
        self._photo_asked = None

    def start(self) -> None:
        self._loop.start()

    async def close(self) -> None:
        await self._loop.close()

    async def _feed_once(self) -> None:
        client = self.cam.client
        if client is None or not client.connected:
            return
        if client is not self._client:  # a new connection: its feeds know nothing yet
            self._client = client
            self.autopilot.utc_new = self.autopilot.has_time
        sample = self.sample()
        if self._photo_asked is not None and monotonic() - self._photo_asked <= MAX_SHUTTER_LEAD_S:
            # a photo is on its way with the position pushed for its shutter: keep that one until
            # the shutter (a periodic position frame in between would be what the camera tags)
            sample = dataclasses.replace(sample, fix=client.feeds.fix)
        try:
            await apply_sample(client, sample)
        except TopGimbalError as exc:
            log.info("camera feed: %s", exc)
            return
        if sample.time_utc is not None:
            self.autopilot.utc_new = False
        self.samples += 1
        self.state = client.feeds.summary()
