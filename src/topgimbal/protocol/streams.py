"""The model profile's video streams as everyone needs them: stream URLs per lens, ports, picture
sizes and codecs, and the simulated card's file names. Pure (standard library and the catalog), so
the client builds `video_url()` and the MAVLink bridge announces streams without importing any
media code; `topgimbal.video.lens` re-exports these names.

Every per-model fact comes from the model profile (`DeviceModel.video`: URL per lens, horizontal
field of view at 1x, zoom range); nothing here is a second model table. What the profiles do not
carry yet is derived or a documented default of this module, the same for every model:
- picture size: the simulator renders visible streams at 1280x720 (the catalog's GOT frame and
  SkyDroid's smallest VID resolution) and thermal ones at 640x512 (a common 640 thermal core);
  a profile that gains `VideoStream.size_px` is read instead;
- vertical field of view: from the horizontal one and the picture's aspect ratio (a pinhole);
- codec: H.264 unless the profile's stream says `codec`; the setting that switches it (TOPOTEK
  `ENT`, role `encoding`) numbers the streams in the profile's order (ENT 0 = stream=0, the main
  stream; 1 = the sub stream), read from the catalog's own enum.
"""

from __future__ import annotations

import math
import re
from dataclasses import dataclass
from typing import Any
from urllib.parse import urlsplit, urlunsplit

from ..errors import TopGimbalError
from .dialect import Dialect
from .dialects import get_model
from .models import DeviceModel

LENSES = ("visible", "thermal")
RTSP_DEFAULT_PORT = 554
# Used only where a profile gives no field of view (every profile today gives one).
ASSUMED_HFOV_DEG = 60.0
DEFAULT_SIZE_PX = {"visible": (1280, 720), "thermal": (640, 512)}


class VideoError(TopGimbalError):
    """A video request that cannot be met (no such lens, bad URL, no stream)."""


@dataclass(frozen=True)
class StreamSpec:
    """One RTSP stream a camera serves, read from its model profile."""

    lens: str  # "visible" or "thermal" (the profile's VideoStream.lens)
    port: int
    path: str  # with the leading slash and any query, e.g. "/stream=0"
    hfov_deg: float  # horizontal field of view at 1x
    size: tuple[int, int]  # picture size (width, height): the profile's, else DEFAULT_SIZE_PX
    codec: str = "h264"  # what the camera sends by default ("h264" or "h265")
    codec_setting: str | None = None  # the encoding command's `stream` value that switches this stream
    url_template: str = ""  # the profile's URL, "{host}" for the camera's address
    name: str = ""  # the profile's stream name ("main", "sub", "thermal")
    zoom_range_x: tuple[float, float] = (1.0, 1.0)
    size_documented: bool = False  # `size` is the profile's (else this module's default)
    codec_documented: bool = False  # `codec` is the profile's (else H.264 by default)

    @property
    def vfov_deg(self) -> float:
        """Vertical field of view at 1x, from the horizontal one and the aspect ratio."""
        return _vfov(self.hfov_deg, *self.size)

    def url(self, host: str, *, port: int | None = None) -> str:
        """This stream's URL at `host` (IPv6 literals get brackets), optionally on another port."""
        h = f"[{host}]" if ":" in host and not host.startswith("[") else host
        parts = urlsplit(self.url_template.replace("{host}", h))
        if port is None:
            return urlunsplit(parts)
        return urlunsplit(parts._replace(netloc=f"{h}:{port}"))


def _model(model: str | DeviceModel) -> tuple[Any, DeviceModel]:
    try:
        return get_model(model)
    except Exception as exc:  # an unknown name: say which are known
        raise VideoError(f"no model {model!r}: {exc}") from None


def _codec_settings(dialect: Dialect, model: DeviceModel) -> list[str]:
    """The encoding command's `stream` values in wire order ("stream0", "stream1", ...): the
    n-th switches the profile's n-th stream."""
    spec = dialect.by_role("encoding", model)
    if spec is None:
        return []
    for form in spec.describe()["forms"]:
        if form["rw"] == "w" and form["direction"] == "request":
            for f in form["fields"]:
                if f["name"] == "stream":
                    return [v["name"] for v in sorted(f.get("values", ()), key=lambda v: v["raw"])]
    return []


def spec_of(model: DeviceModel, index: int, settings: list[str] | None = None) -> StreamSpec:
    v = model.video[index]
    parts = urlsplit(v.url.replace("{host}", "host"))
    path = parts.path + (f"?{parts.query}" if parts.query else "")
    size_px = getattr(v, "size_px", None)
    codec = getattr(v, "codec", None)
    size = size_px or DEFAULT_SIZE_PX.get(v.lens, DEFAULT_SIZE_PX["visible"])
    settings = settings or []
    return StreamSpec(
        lens=v.lens,
        port=parts.port or RTSP_DEFAULT_PORT,
        path=path or "/",
        hfov_deg=float(v.hfov_deg) if v.hfov_deg else ASSUMED_HFOV_DEG,
        size=(int(size[0]), int(size[1])),
        codec=str(codec or "h264"),
        codec_setting=settings[index] if index < len(settings) else None,
        url_template=v.url,
        name=v.name,
        zoom_range_x=tuple(v.zoom_range_x),  # type: ignore[arg-type]
        size_documented=bool(size_px),
        codec_documented=bool(codec),
    )


def streams_for(model: str | DeviceModel) -> tuple[StreamSpec, ...]:
    """The RTSP streams of a model, from its profile (one per lens, in the profile's order)."""
    dialect, m = _model(model)
    if not m.video:
        raise VideoError(f"the {m.name} profile lists no video stream")
    settings = _codec_settings(dialect, m)
    out: list[StreamSpec] = []
    for i, v in enumerate(m.video):
        if all(s.lens != v.lens for s in out):  # the first stream of each lens
            out.append(spec_of(m, i, settings))
    return tuple(out)


def stream_for(model: str | DeviceModel, lens: str = "visible") -> StreamSpec:
    streams = streams_for(model)
    for s in streams:
        if s.lens == lens:
            return s
    have = ", ".join(s.lens for s in streams)
    name = model if isinstance(model, str) else model.name
    raise VideoError(f"the {name} has no {lens!r} stream; it has: {have}")


def video_url(model: str | DeviceModel, host: str, lens: str = "visible", *, port: int | None = None) -> str:
    """The RTSP URL of a lens's stream on a camera at `host` (IPv6 literals get brackets)."""
    if lens not in LENSES:
        raise VideoError(f"lens must be one of {', '.join(LENSES)} (got {lens!r})")
    return stream_for(model, lens).url(host, port=port)


def plan_ports(specs: tuple[StreamSpec, ...], port: int | None) -> dict[int, int]:
    """Documented port -> port to use. An override keeps the documented spacing (554/555 ->
    N/N+1); 0 gives each documented port its own free port. The simulator binds these; the
    MAVLink bridge announces them (`--video-port`)."""
    documented = sorted({s.port for s in specs})
    if port is None:
        return {p: p for p in documented}
    if port == 0:
        return {p: 0 for p in documented}
    if not 0 < port <= 65535 or port + (documented[-1] - documented[0]) > 65535:
        raise VideoError(
            f"port {port} leaves no room for every stream (they keep the documented spacing "
            f"{', '.join(map(str, documented))}): give 1..{65535 - (documented[-1] - documented[0])}, or 0 for free ports"
        )
    return {p: port + (p - documented[0]) for p in documented}


def stream_urls(model: str | DeviceModel, host: str, *, port: int | None = None) -> dict[str, str]:
    """{lens: URL} of every stream at `host`; `port` moves the first stream's port there and
    the others keep the documented spacing (a camera behind a port forward, a simulator on a
    free port)."""
    specs = streams_for(model)
    ports = plan_ports(specs, port) if port else {s.port: s.port for s in specs}
    return {s.lens: s.url(host, port=ports[s.port] if port else None) for s in specs}


def host_of(url: str) -> str:
    """The host part of a control URL (udp://H:P, tcp://H:P); serial URLs have none."""
    parts = urlsplit(url)
    if parts.scheme not in ("udp", "tcp") or not parts.hostname:
        raise VideoError(
            f"cannot tell the camera's IP address from {url!r}: give host=... (the camera's network address)"
        )
    return parts.hostname


def _vfov(hfov_deg: float, width_px: int, height_px: int) -> float:
    """A pinhole's vertical field of view (geo.optics.vfov_for; the protocol core imports no geo)."""
    return math.degrees(2.0 * math.atan(math.tan(math.radians(hfov_deg) / 2.0) * height_px / width_px))


# -- file names on the simulated card (video/media.py says why): pure, so the MAVLink bridge can
# name a photo's file_url without loading the renderer.

MEDIA_NAME = re.compile(r"^(IMG_\d{4,}(_T)?\.jpg|snap_[01]_\d+\.jpeg|stream_0_\d+\.mp4|VID_\d{4,}\.mp4)$")


def photo_names(dialect: str, index: int, lenses: list[str]) -> dict[str, str]:
    if dialect == "topotek":
        return {lens: f"snap_{int(lens == 'thermal')}_{index}.jpeg" for lens in lenses}
    return {lens: f"IMG_{index:04d}{'_T' if lens == 'thermal' else ''}.jpg" for lens in lenses}


def recording_name(dialect: str, index: int) -> str:
    return f"stream_0_{index}.mp4" if dialect == "topotek" else f"VID_{index:04d}.mp4"
