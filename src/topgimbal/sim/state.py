"""The camera's non-gimbal state: lens, recording, storage, network and stored settings.

Plain data plus the small amount of time behaviour that belongs to it (zoom and focus motors that
move while a zoom command runs, SD space that falls while recording). `snapshot()` / `restore()`
give the persistent part as JSON-ready dicts.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from datetime import datetime, timedelta
from functools import cache
from typing import Any

from ..protocol import DIALECT_NAMES, QUERY, DeviceModel, get_dialect
from ..protocol.commands import stored_form

# Zoom motor position range. The documents give zoom positions as signed 16-bit values without a
# scale; the simulator maps 0..ZOOM_POS_MAX linearly onto 1x..optical_zoom_max.
ZOOM_POS_MAX = 4000
ZOOM_FULL_TRAVEL_S = 4.0  # wide to tele while ZMC zoom_in runs
FOCUS_POS_MAX = 2000
FOCUS_RATE = 500.0  # focus positions per second while FCC +/- runs
DIGITAL_ZOOM_RATE = 1.0  # x per second while TOPOTEK DZM 0C / 0D runs
PHOTO_MB = 6
SD_TOTAL_MB = 30436  # a 32 GB card as the camera reports it
# A camera without a clock (the no_clock quirk) starts here at power-on and counts from there.
NO_CLOCK_EPOCH = datetime(1970, 1, 1)


@dataclass
class HostFeed:
    """What the host tells the camera about the vehicle (LAT/LON/ALT/AZI/GPS), as the camera keeps
    it: each value unset until told (by role: the one position type is geo.Geodetic; this is a
    camera's memory of a feed, client.feeds.FedPosition the feed a user sends)."""

    lat_deg: float | None = None
    lon_deg: float | None = None
    alt_m: float | None = None
    azimuth_deg: float | None = None
    speed_m_s: float = 0.0


NETWORK_KEY = "network."


@cache
def network_factory(key: str) -> str:
    """The catalog's factory value of a network setting (`ip`, `gateway`...), found by its state
    key; both dialects build these rows alike."""
    for name in DIALECT_NAMES:
        for spec in get_dialect(name).commands.values():
            for f in (stored_form(spec) or QUERY).fields:
                if f.state_key == NETWORK_KEY + key and f.factory is not None:
                    return str(f.factory)
    return "0.0.0.0"


@dataclass
class NetworkState:
    """Stored and answered, never bound: the simulator always listens on loopback. A new camera's
    values are the catalog's factory values."""

    ip: str = field(default_factory=lambda: network_factory("ip"))
    gateway: str = field(default_factory=lambda: network_factory("gateway"))
    dns: str = field(default_factory=lambda: network_factory("dns"))
    backup_dns: str = field(default_factory=lambda: network_factory("backup_dns"))

    def snapshot(self) -> dict[str, Any]:
        return dict(self.__dict__)

    def restore(self, d: dict[str, Any]) -> None:
        for k in self.__dict__:
            if isinstance(d.get(k), str):
                setattr(self, k, d[k])


@dataclass(slots=True)
class CameraState:
    model: DeviceModel  # the lens limits are the profile's, not a copy
    recording: bool = False
    record_started: float = 0.0
    photos_taken: int = 0
    record_index: int = 0
    photo_index: int = 0
    sd_present: bool = True
    sd_total_mb: int = SD_TOTAL_MB
    sd_used_mb: float = 0.0
    bitrate_kbps: int = 4000
    zoom_pos: float = 0.0
    zoom_dir: int = 0  # -1 out, 0 still, +1 in
    focus_pos: float = 1000.0
    focus_dir: int = 0
    autofocus: bool = True
    digital_zoom_x: float = 1.0
    thermal_digital_zoom_x: float = 1.0
    digital_zoom_dir: int = 0
    day_night: str = "day"
    time_set: datetime | None = None
    time_set_at: float = 0.0
    # Whether video output has started: VOM output on, or a video client playing (the video
    # package sets it). Camera commands wait for it on models with the needs_video_output quirk.
    video_output: bool = False
    booted_at: float = 0.0  # device time of power-on (the no-clock camera counts from it)
    tracking: str = "stopped"
    rangefinder: str = "stop"
    events: list[str] = field(default_factory=list)  # "zoom_stopped" etc., consumed by the device

    # -- lens ----------------------------------------------------------------------------------

    @property
    def optical_zoom_max(self) -> float:
        return self.model.optical_zoom_max

    @property
    def digital_zoom_max(self) -> float:
        return self.model.digital_zoom_max

    @property
    def optical_zoom_x(self) -> float:
        return round(1.0 + (self.optical_zoom_max - 1.0) * self.zoom_pos / ZOOM_POS_MAX, 1)

    @property
    def zoom_x(self) -> float:
        """Effective magnification of the visible image: optical times digital."""
        return round(self.optical_zoom_x * self.digital_zoom_x, 2)

    def set_magnification(self, x: float) -> None:
        x = max(1.0, min(self.optical_zoom_max, x))
        span = self.optical_zoom_max - 1.0
        self.zoom_pos = 0.0 if span <= 0 else (x - 1.0) / span * ZOOM_POS_MAX

    def clock(self, now: float, *, has_clock: bool = True) -> datetime | None:
        """The camera's time at device time `now`: what the host last set (TIM / UTC) moved on by
        the time since; before that the 1970 epoch plus uptime on a camera without a clock, None
        (the real time, which the simulator does not model) on one with."""
        if self.time_set is not None:
            return self.time_set + timedelta(seconds=max(0.0, now - self.time_set_at))
        return NO_CLOCK_EPOCH + timedelta(seconds=max(0.0, now - self.booted_at)) if not has_clock else None

    @property
    def sd_remaining_mb(self) -> int:
        return max(0, int(self.sd_total_mb - self.sd_used_mb)) if self.sd_present else 0

    @property
    def moving(self) -> bool:
        return bool(self.zoom_dir or self.focus_dir or self.digital_zoom_dir)

    def advance(self, dt: float) -> None:
        if dt <= 0:
            return
        if self.zoom_dir:
            self.zoom_pos += self.zoom_dir * ZOOM_POS_MAX / ZOOM_FULL_TRAVEL_S * dt
            if not 0 <= self.zoom_pos <= ZOOM_POS_MAX:
                self.zoom_pos = min(float(ZOOM_POS_MAX), max(0.0, self.zoom_pos))
                self.zoom_dir = 0
                self.events.append("zoom_stopped")
        if self.focus_dir:
            self.focus_pos = min(float(FOCUS_POS_MAX), max(0.0, self.focus_pos + self.focus_dir * FOCUS_RATE * dt))
        if self.digital_zoom_dir:
            z = self.digital_zoom_x + self.digital_zoom_dir * DIGITAL_ZOOM_RATE * dt
            self.digital_zoom_x = min(self.digital_zoom_max, max(1.0, z))
            if self.digital_zoom_x in (1.0, self.digital_zoom_max):
                self.digital_zoom_dir = 0
        if self.recording and self.sd_present:
            # The recording eats the card at the stream's bitrate.
            self.sd_used_mb = min(float(self.sd_total_mb), self.sd_used_mb + self.bitrate_kbps / 8000.0 * dt)

    # -- persistence ---------------------------------------------------------------------------

    def snapshot(self) -> dict[str, Any]:
        return {
            "record_index": self.record_index,
            "photo_index": self.photo_index,
            "photos_taken": self.photos_taken,
            "sd_present": self.sd_present,
            "sd_total_mb": self.sd_total_mb,
            "sd_used_mb": round(self.sd_used_mb, 3),
            "zoom_pos": round(self.zoom_pos, 1),
            "focus_pos": round(self.focus_pos, 1),
            "digital_zoom_x": self.digital_zoom_x,
            "day_night": self.day_night,
            "bitrate_kbps": self.bitrate_kbps,
        }

    def restore(self, d: dict[str, Any]) -> None:
        for k in self.snapshot():
            if k in d and isinstance(d[k], (int, float, bool, str)):
                setattr(self, k, type(getattr(self, k))(d[k]))
