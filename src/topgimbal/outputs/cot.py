"""Cursor-on-Target for TAK (ATAK, WinTAK, TAK Server): `--cot URL` sends, once a second, what
the camera looks at, built with the field's own library (pytak, the `cot` extra):

- the vehicle (type a-f-A-M-F-Q, a friendly UAV) at its position, whose `<sensor>` detail draws
  the camera's field of view on the map (azimuth, elevation, fov, vfov, range, roll; ATAK's
  sensor fields) and whose `<__video>` detail carries the camera's RTSP URL;
- the sensor point of interest (type b-m-p-s-p-i, "SPI") where the image centre lands, linked to
  the vehicle, with the geolocation's error estimate as its circular error (ce);
- the footprint (type u-d-f, a closed free-form shape) through the picture's four corners, when
  all four land.

Each is one complete XML event: a datagram of its own over udp://, one after another on a TAK
server's tcp:// or tls:// stream (cot_stream.py). Heights are `hae`, above the WGS84 ellipsoid:
the MSL altitudes plus the EGM96 geoid undulation (geo/geoid.py); without the geoid grid `hae`
is CoT's "unknown" (9999999.0), never the MSL altitude. An event is well-formed XML of at most
MAX_EVENT_BYTES whatever the names and URLs given: characters XML 1.0 forbids are replaced, and an
event too long loses its optional details, or is not sent (a log line says which). Times come
from topgimbal.clock.wall_time. Pure but for `CotSender`."""

from __future__ import annotations

import asyncio
import datetime
import logging
import math
import re
import xml.etree.ElementTree as ET
from collections.abc import Callable
from urllib.parse import urlsplit

from ..clock import wall_time
from ..geo.earth import wrap360
from ..geo.geoid import ellipsoid_height
from ..logthrottle import ThrottledLog
from .cot_stream import CotConfigError, CotTls, StreamOut, UdpOut, open_out, parse_url, ssl_context
from .sighting import Sighting

__all__ = ["CotConfigError", "CotSender", "CotTls", "Sighting", "check_text", "events", "parse_target"]

log = logging.getLogger("topgimbal.mavlink")
throttled = ThrottledLog(log, every_s=60.0)

STALE_S = 5  # an event outlives a missed second or two, then the map drops it
COT_HZ = 1.0
MAX_EVENT_BYTES = 8192  # a datagram's worth, on every transport; ours are about 1 KB
MAX_DATAGRAM = MAX_EVENT_BYTES  # the old name
UNKNOWN = 9999999.0  # CoT's "not known" for hae, ce and le
MAX_NAME_CHARS = 256  # a uid or callsign
# what XML 1.0 cannot carry at all (its Char production): C0 controls but tab, CR, LF; surrogates; FFFE, FFFF
_NOT_XML = re.compile("[^\t\n\r\x20-\ud7ff\ue000-\ufffd\U00010000-\U0010ffff]")
# what a name or URL given must not hold: every control character (C0, DEL, C1), surrogates, non-characters
_BAD_TEXT = re.compile("[\x00-\x1f\x7f-\x9f\ud800-\udfff\ufffe\uffff]")
OPTIONAL_DETAILS = ("__video", "remarks", "precisionlocation", "sensor")  # given up in this order when too long


def check_text(what: str, value: str, max_chars: int = 2048) -> str:
    """`value` as a CoT name or URL; CotConfigError for control characters or too long."""
    bad = _BAD_TEXT.search(value)
    if bad:
        raise CotConfigError(f"{what} {value[:80]!r}: control character U+{ord(bad.group()):04X} at {bad.start()} "
                             "(XML cannot carry it)")  # fmt: skip
    if len(value) > max_chars:
        raise CotConfigError(f"{what}: {len(value)} characters, at most {max_chars}")
    return value


def check_config(url: str | None, tls: CotTls | None, video_urls: list[str] | None) -> None:
    """A bridge's CoT options, before anything starts: CotConfigError for a target that is not
    udp/tcp/tls://HOST:PORT, TLS files that cannot be used, video URLs XML cannot carry."""
    for u in video_urls or []:  # also sent in VIDEO_STREAM_INFORMATION: checked with or without CoT
        check_text("video URL", u)
    if url is not None:
        ssl_context(parse_url(url), tls)


def cot_names(sysid: int, model: str, name: str | None) -> tuple[str, str]:
    """(uid, callsign): several cameras of one system (multi.py) each need their own uid (the
    map keeps one marker per uid), so each goes by its name; one camera alone by its model."""
    if name:
        return f"topgimbal-{sysid}-{name}", f"{name} {sysid}"
    return f"topgimbal-{model}-{sysid}", f"{model} {sysid}"


def _xml_text(value: str) -> str:
    return _NOT_XML.sub("\ufffd", value)


def parse_target(url: str) -> tuple[str, int]:
    """udp://, tcp:// or tls://HOST:PORT -> (host, port); CotConfigError otherwise."""
    t = parse_url(url)
    return t.host, t.port


def _time(t: float) -> str:
    return datetime.datetime.fromtimestamp(t, datetime.timezone.utc).strftime("%Y-%m-%dT%H:%M:%S.%fZ")


def _hae(lat: float, lon: float, msl_m: float) -> float | None:
    return ellipsoid_height(lat, lon, msl_m)


def _event(
    uid: str, cot_type: str, lat: float, lon: float, msl_m: float, ce: float, now: float, how: str
) -> ET.Element:
    import pytak  # the cot extra; checked when the sender starts

    hae = _hae(lat, lon, msl_m)
    # pytak truncates to 4 decimals (11 m) by default: a target needs 7 (1 cm)
    point = pytak.cot_point(lat, lon, f"{ce:.1f}", f"{hae:.2f}" if hae is not None else f"{UNKNOWN:.1f}",
                            f"{UNKNOWN:.1f}", precision=7)  # fmt: skip
    ev: ET.Element = pytak.cot_event(uid=uid, cot_type=cot_type, how=how, stale=STALE_S, point=point, flow_tag=False)
    ev.set("time", _time(now))  # the one clock, not the library's own reading
    ev.set("start", _time(now))
    ev.set("stale", _time(now + STALE_S))
    return ev


def _f(v: float) -> str:
    return f"{v:.7f}" if abs(v) <= 360 else f"{v:.2f}"


def _known(*values: float) -> bool:
    return all(math.isfinite(v) for v in values)


def events(s: Sighting, *, uid: str, callsign: str, now: float | None = None) -> list[bytes]:
    """The CoT events of one sighting, each a complete, well-formed XML document of at most
    MAX_EVENT_BYTES. None at all for a vehicle at 0, 0 or at no finite position (an autopilot
    before its first fix): an unknown position is not sent."""
    t = wall_time() if now is None else now
    lat, lon = s.vehicle_lat_deg, s.vehicle_lon_deg
    if not _known(lat, lon, s.vehicle_alt_m) or (lat == 0.0 and lon == 0.0):
        return []
    uid, callsign = _xml_text(uid), _xml_text(callsign)
    out = []
    vehicle = _event(uid, "a-f-A-M-F-Q", lat, lon, s.vehicle_alt_m, 10.0, t, "m-g")
    detail = vehicle.find("detail")
    assert detail is not None
    ET.SubElement(detail, "contact", callsign=callsign)
    sensor = ET.SubElement(detail, "sensor")
    sensor.set("azimuth", f"{wrap360(s.azimuth_deg):.2f}")
    sensor.set("elevation", f"{s.elevation_deg:.2f}")
    sensor.set("roll", f"{s.roll_deg:.2f}")
    sensor.set("fov", f"{s.hfov_deg:.3f}")
    sensor.set("vfov", f"{s.vfov_deg:.3f}")
    sensor.set("range", f"{s.target.range_m:.1f}" if s.target is not None else "0")
    sensor.set("type", "r-e")  # ATAK: an electro-optical sensor
    sensor.set("model", callsign)
    sensor.set("displayMagneticReference", "0")
    if s.video_url:
        url = _xml_text(s.video_url)
        try:
            parts = urlsplit(url)
            port = parts.port or 554
        except ValueError:  # not a URL a TAK client could open: no video entry
            parts, port = None, 0
        if parts is not None:
            video = ET.SubElement(detail, "__video", url=url, uid=f"{uid}.video")
            ET.SubElement(video, "ConnectionEntry", address=parts.hostname or "", uid=f"{uid}.video",
                          alias=callsign, protocol=parts.scheme or "rtsp", port=str(port),
                          path=parts.path or "/")  # fmt: skip
    out.append(vehicle)
    g = s.target
    if g is not None and _known(g.lat_deg, g.lon_deg, g.alt_m, g.error_m, g.range_m):
        spi = _event(f"{uid}.SPI", "b-m-p-s-p-i", g.lat_deg, g.lon_deg, g.alt_m, g.error_m, t, "m-c")
        d = spi.find("detail")
        assert d is not None
        ET.SubElement(d, "contact", callsign=f"{callsign} SPI")
        ET.SubElement(d, "link", uid=uid, type="a-f-A-M-F-Q", relation="p-p")
        ET.SubElement(
            d, "remarks"
        ).text = f"source {g.source}, error {g.error_m:.1f} m (1 sigma), range {g.range_m:.1f} m"
        ET.SubElement(d, "precisionlocation", geopointsrc=_xml_text(g.source),
                      altsrc="DTED0" if "terrain" in g.source else "???")  # fmt: skip
        out.append(spi)
    cs = [c for c in s.corners if c is not None and _known(c.lat_deg, c.lon_deg, c.alt_m)]
    if s.corners and len(cs) == len(s.corners):
        clat = sum(c.lat_deg for c in cs) / len(cs)
        clon = sum(c.lon_deg for c in cs) / len(cs)
        shape = _event(f"{uid}.footprint", "u-d-f", clat, clon, sum(c.alt_m for c in cs) / len(cs), UNKNOWN, t, "h-e")
        d = shape.find("detail")
        assert d is not None
        for c in [*cs, cs[0]]:
            hae = _hae(c.lat_deg, c.lon_deg, c.alt_m)  # a link point's height is hae too: left out unknown
            ET.SubElement(d, "link", point=f"{_f(c.lat_deg)},{_f(c.lon_deg)}" + (f",{hae:.1f}" if hae is not None
                                                                                   else ""))  # fmt: skip
        ET.SubElement(d, "contact", callsign=f"{callsign} footprint")
        ET.SubElement(d, "strokeColor", value="-256")
        ET.SubElement(d, "strokeWeight", value="2.0")
        ET.SubElement(d, "labels_on", value="false")
        out.append(shape)
    return [data for e in out if (data := _fit(e)) is not None]


def _serialise(e: ET.Element) -> bytes:
    # encoding="unicode" then UTF-8: the declaration says UTF-8 (ElementTree's default writes
    # ASCII with character references, also well-formed, but longer)
    return b'<?xml version="1.0" encoding="UTF-8"?>\n' + ET.tostring(e, encoding="unicode").encode("utf-8")


def _fit(e: ET.Element) -> bytes | None:
    """`e` as bytes within MAX_EVENT_BYTES: its optional details given up one by one while too
    long (logged); None (logged) when even the bare event is. Never cut: a cut event is not XML."""
    data = _serialise(e)
    detail = e.find("detail")
    dropped = []
    for name in OPTIONAL_DETAILS:
        if len(data) <= MAX_EVENT_BYTES or detail is None:
            break
        for child in detail.findall(name):
            detail.remove(child)
            dropped.append(name)
        data = _serialise(e)
    uid = e.get("uid", "")[:80]
    if len(data) > MAX_EVENT_BYTES:
        throttled.warning(f"cot-long-{e.get('type')}", "CoT %s %s: %d bytes even without its optional details, "
                          "more than %d: not sent", e.get("type"), uid, len(data), MAX_EVENT_BYTES)  # fmt: skip
        return None
    if dropped:
        throttled.warning(f"cot-cut-{e.get('type')}", "CoT %s %s: longer than %d bytes: sent without its %s",
                          e.get("type"), uid, MAX_EVENT_BYTES, ", ".join(dropped))  # fmt: skip
    return data


class CotSender:
    """Sends `sighting()`'s events at COT_HZ (nothing when it returns None) to a udp://, tcp:// or
    tls:// target (cot_stream.py); `tls`: the client certificate and CA for tls://."""

    def __init__(
        self,
        url: str,
        sighting: Callable[[], Sighting | None],
        *,
        uid: str,
        callsign: str,
        rate_hz: float = COT_HZ,
        tls: CotTls | None = None,
    ) -> None:
        self.uid = check_text("CoT uid", uid, MAX_NAME_CHARS)
        self.callsign = check_text("CoT callsign", callsign, MAX_NAME_CHARS)
        self.out: UdpOut | StreamOut = open_out(url, tls)
        self.target = self.out.target
        self.address = (self.target.host, self.target.port)
        self.sighting = sighting
        self.period_s = 1.0 / rate_hz
        try:
            import pytak  # noqa: F401 - fail at start, not at the first second
        except ImportError as e:  # pragma: no cover - depends on the installation
            raise CotConfigError("Cursor-on-Target needs pytak: pip install 'topgimbal[cot]'") from e

    @property
    def sent(self) -> int:
        return self.out.sent

    async def run(self) -> None:
        link = asyncio.ensure_future(self.out.run())
        waiting = False  # said once: nothing goes out until the autopilot's position and heading are heard
        try:
            while True:
                try:
                    s = self.sighting()
                    if s is None and not waiting:
                        log.info("CoT %s: no vehicle position and heading (or camera attitude) yet: sending nothing",
                                 self.uid)  # fmt: skip
                    elif s is not None and waiting:
                        log.info("CoT %s: sending to %s", self.uid, self.target)
                    waiting = s is None
                    for data in events(s, uid=self.uid, callsign=self.callsign) if s is not None else []:
                        self.out.offer(data)
                except OSError as exc:  # unreachable network: say so once a while, keep going
                    throttled.warning("cot-send", "CoT to %s: %s", self.target, exc)
                if link.done():  # the link's task ended: its error is a bug worth seeing
                    link.result()
                await asyncio.sleep(self.period_s)
        finally:
            link.cancel()
            self.out.close()
