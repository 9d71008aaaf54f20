"""Per-model video facts and the lens model: stream URLs, field of view, pixel <-> angle.

Pure (standard library only), so the client can build `video_url()` without importing the
renderer or any media library.

THE TABLE BELOW IS TEMPORARY: the model profiles (`protocol.DeviceModel`) will carry these facts;
when they do, `streams_for()` reads the profile instead (one line) and the table goes.
Sources: TOPOTEK §二 "码流（RTSP）" gives rtsp://IP:554/stream=0 (main) and stream=1 (sub); its
recording names say stream 0 is the visible camera and stream 1 the thermal one, and ENT (§17)
switches each between H.264 and H.265. The SkyDroid document gives no RTSP URL; public client code
for the C12 and C13 uses rtsp://IP:554/stream=1 (visible) and rtsp://IP:555/stream=2 (thermal).
Fields of view are not in either document: they are the simulator's choices (typical 1x wide
lenses; the thermal one is sim/scene.py's, which the TMP reports already use).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from urllib.parse import urlsplit

from ..errors import TopGimbalError

LENSES = ("visible", "thermal")


class VideoError(TopGimbalError):
    """A video request that cannot be met (no such lens, bad URL, no stream)."""


@dataclass(frozen=True)
class StreamSpec:
    """One RTSP stream a camera serves."""

    lens: str  # "visible" or "thermal"
    port: int
    path: str  # with the leading slash, e.g. "/stream=0"
    hfov_deg: float  # horizontal field of view at 1x
    size: tuple[int, int]  # the simulator's default picture size (width, height)
    codec: str = "h264"  # what the camera sends by default ("h264" or "h265")
    codec_setting: str | None = None  # the ENT `stream` value that switches this stream's codec


# Thermal: the field of view sim/scene.py's temperature picture uses (32 x 26 deg at 640 x 512).
_THERMAL_HFOV_DEG = 32.0
_VISIBLE_HFOV_DEG = 62.0

_SKYDROID_VISIBLE = StreamSpec("visible", 554, "/stream=1", _VISIBLE_HFOV_DEG, (1280, 720))
_SKYDROID_THERMAL = StreamSpec("thermal", 555, "/stream=2", _THERMAL_HFOV_DEG, (640, 512))
STREAMS: dict[str, tuple[StreamSpec, ...]] = {
    "C10": (_SKYDROID_VISIBLE,),
    "C10Pro": (_SKYDROID_VISIBLE,),
    "C12": (_SKYDROID_VISIBLE, _SKYDROID_THERMAL),
    "C13": (_SKYDROID_VISIBLE, _SKYDROID_THERMAL),
    "C20": (_SKYDROID_VISIBLE,),
    "SIP": (
        StreamSpec("visible", 554, "/stream=0", _VISIBLE_HFOV_DEG, (1280, 720), codec_setting="stream0"),
        StreamSpec("thermal", 554, "/stream=1", _THERMAL_HFOV_DEG, (640, 512), codec_setting="stream1"),
    ),
}


def streams_for(model: str) -> tuple[StreamSpec, ...]:
    """The RTSP streams of a model (its documented ports and paths)."""
    for name, streams in STREAMS.items():
        if name.lower() == model.lower():
            return streams
    raise VideoError(f"no video facts for model {model!r}; known: {', '.join(STREAMS)}")


def stream_for(model: str, lens: str = "visible") -> StreamSpec:
    streams = streams_for(model)
    for s in streams:
        if s.lens == lens:
            return s
    have = ", ".join(s.lens for s in streams)
    raise VideoError(f"the {model} has no {lens!r} stream; it has: {have}")


def video_url(model: str, host: str, lens: str = "visible", *, port: int | None = None) -> str:
    """The RTSP URL of a lens's stream on a camera at `host` (IPv6 literals get brackets)."""
    if lens not in LENSES:
        raise VideoError(f"lens must be one of {', '.join(LENSES)} (got {lens!r})")
    s = stream_for(model, lens)
    h = f"[{host}]" if ":" in host and not host.startswith("[") else host
    return f"rtsp://{h}:{s.port if port is None else port}{s.path}"


def host_of(url: str) -> str:
    """The host part of a control URL (udp://H:P, tcp://H:P); serial URLs have none."""
    parts = urlsplit(url)
    if parts.scheme not in ("udp", "tcp") or not parts.hostname:
        raise VideoError(
            f"cannot tell the camera's IP address from {url!r}: give host=... (the camera's network address)"
        )
    return parts.hostname


# -- the lens model ------------------------------------------------------------------------------


def hfov_at(hfov_1x_deg: float, zoom_x: float) -> float:
    """Horizontal field of view at a magnification (a pinhole: the focal length scales)."""
    z = max(1.0, float(zoom_x))
    return math.degrees(2.0 * math.atan(math.tan(math.radians(hfov_1x_deg) / 2.0) / z))


def focal_px(width_px: int, hfov_deg: float) -> float:
    return (width_px / 2.0) / math.tan(math.radians(hfov_deg) / 2.0)


def basis(yaw_deg: float, pitch_deg: float, roll_deg: float) -> tuple[Vec, Vec, Vec]:
    """Forward, right and up unit vectors of a camera, in a world frame x north, y east, z up.
    Yaw is right-positive (a bearing), pitch up-positive, roll right-positive (right side down)."""
    y, p, r = (math.radians(a) for a in (yaw_deg, pitch_deg, roll_deg))
    fwd = (math.cos(p) * math.cos(y), math.cos(p) * math.sin(y), math.sin(p))
    right0 = (-math.sin(y), math.cos(y), 0.0)
    up0 = (-math.sin(p) * math.cos(y), -math.sin(p) * math.sin(y), math.cos(p))
    cr, sr = math.cos(r), math.sin(r)
    right = tuple(a * cr - b * sr for a, b in zip(right0, up0, strict=False))
    up = tuple(b * cr + a * sr for a, b in zip(right0, up0, strict=False))
    return fwd, right, up  # type: ignore[return-value]


Vec = tuple[float, float, float]


def direction(az_deg: float, el_deg: float) -> Vec:
    a, e = math.radians(az_deg), math.radians(el_deg)
    return (math.cos(e) * math.cos(a), math.cos(e) * math.sin(a), math.sin(e))


@dataclass(frozen=True)
class View:
    """Where a camera looks and how wide: enough to map pixels to bearings and back."""

    yaw_deg: float
    pitch_deg: float
    roll_deg: float
    hfov_deg: float
    width_px: int
    height_px: int

    @property
    def focal_px(self) -> float:
        return focal_px(self.width_px, self.hfov_deg)

    def project(self, az_deg: float, el_deg: float) -> tuple[float, float] | None:
        """Pixel (x, y) of an earth-frame direction, or None behind the camera."""
        fwd, right, up = basis(self.yaw_deg, self.pitch_deg, self.roll_deg)
        d = direction(az_deg, el_deg)
        zc = _dot(d, fwd)
        if zc <= 1e-6:
            return None
        f = self.focal_px
        return self.width_px / 2.0 + f * _dot(d, right) / zc, self.height_px / 2.0 - f * _dot(d, up) / zc

    def angles_at(self, x_px: float, y_px: float) -> tuple[float, float]:
        """Earth-frame (bearing, elevation) in degrees of what is at pixel (x, y)."""
        fwd, right, up = basis(self.yaw_deg, self.pitch_deg, self.roll_deg)
        f = self.focal_px
        a = (x_px - self.width_px / 2.0) / f
        b = (self.height_px / 2.0 - y_px) / f
        ray = tuple(fw + a * r + b * u for fw, r, u in zip(fwd, right, up, strict=False))
        n = math.sqrt(sum(c * c for c in ray))
        az = math.degrees(math.atan2(ray[1], ray[0]))
        el = math.degrees(math.asin(max(-1.0, min(1.0, ray[2] / n))))
        return (az + 180.0) % 360.0 - 180.0, el


def _dot(a: Vec, b: Vec) -> float:
    return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]


def wrap180(a: float) -> float:
    return (a + 180.0) % 360.0 - 180.0
