"""Cursor-on-Target for TAK (ATAK, WinTAK, TAK Server): `--cot udp://HOST:PORT` sends, once a
second, what the camera looks at, built with the field's own library (pytak, the `cot` extra):

- the vehicle (type a-f-A-M-F-Q, a friendly UAV) at its position, whose `<sensor>` detail draws
  the camera's field of view on the map (azimuth, elevation, fov, vfov, range, roll; ATAK's
  sensor fields) and whose `<__video>` detail carries the camera's RTSP URL;
- the sensor point of interest (type b-m-p-s-p-i, "SPI") where the image centre lands, linked to
  the vehicle, with the geolocation's error estimate as its circular error (ce);
- the footprint (type u-d-f, a closed free-form shape) through the picture's four corners, when
  all four land.

Each is an XML event in its own datagram (TAK's plain-XML mesh form, which every TAK client and
takproto read). Times come from topgimbal.clock.wall_time. Pure but for `CotSender`."""

from __future__ import annotations

import asyncio
import contextlib
import datetime
import logging
import socket
import xml.etree.ElementTree as ET
from collections.abc import Callable
from dataclasses import dataclass
from urllib.parse import urlsplit

from ..clock import wall_time
from ..errors import TopGimbalError
from ..geo import Fix as GeoFix
from ..geo.earth import wrap360

log = logging.getLogger("topgimbal.mavlink")

STALE_S = 5  # an event outlives a missed second or two, then the map drops it
COT_HZ = 1.0
MAX_DATAGRAM = 8192  # one event per datagram; ours are about 1 KB


class CotConfigError(TopGimbalError, ValueError):
    kind = "cot"


@dataclass(frozen=True)
class Sighting:
    """What one CoT update says: the vehicle, where the camera looks, the picture's corners."""

    vehicle_lat_deg: float
    vehicle_lon_deg: float
    vehicle_alt_m: float  # MSL (CoT's hae is height above the ellipsoid: see docs/errata.md)
    azimuth_deg: float  # the optical axis, earth frame
    elevation_deg: float
    roll_deg: float
    hfov_deg: float
    vfov_deg: float
    target: GeoFix | None
    corners: list[GeoFix | None]
    video_url: str | None = None


def parse_target(url: str) -> tuple[str, int]:
    """udp://HOST:PORT -> (host, port); CotConfigError otherwise."""
    parts = urlsplit(url)
    if parts.scheme != "udp" or not parts.hostname or parts.port is None:
        raise CotConfigError(f"--cot {url!r}: expected udp://HOST:PORT (e.g. udp://239.2.3.1:6969)")
    return parts.hostname, parts.port


def _time(t: float) -> str:
    return datetime.datetime.fromtimestamp(t, datetime.timezone.utc).strftime("%Y-%m-%dT%H:%M:%S.%fZ")


def _event(uid: str, cot_type: str, lat: float, lon: float, hae: float, ce: float, now: float, how: str) -> ET.Element:
    import pytak  # the cot extra; checked when the sender starts

    # pytak truncates to 4 decimals (11 m) by default: a target needs 7 (1 cm)
    point = pytak.cot_point(lat, lon, f"{ce:.1f}", f"{hae:.2f}", "9999999.0", precision=7)
    ev: ET.Element = pytak.cot_event(uid=uid, cot_type=cot_type, how=how, stale=STALE_S, point=point, flow_tag=False)
    ev.set("time", _time(now))  # the one clock, not the library's own reading
    ev.set("start", _time(now))
    ev.set("stale", _time(now + STALE_S))
    return ev


def _f(v: float) -> str:
    return f"{v:.7f}" if abs(v) <= 360 else f"{v:.2f}"


def events(s: Sighting, *, uid: str, callsign: str, now: float | None = None) -> list[bytes]:
    """The CoT events of one sighting, each a complete XML document."""
    t = wall_time() if now is None else now
    out = []
    vehicle = _event(uid, "a-f-A-M-F-Q", s.vehicle_lat_deg, s.vehicle_lon_deg, s.vehicle_alt_m, 10.0, t, "m-g")
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
        video = ET.SubElement(detail, "__video", url=s.video_url, uid=f"{uid}.video")
        ET.SubElement(video, "ConnectionEntry", address=urlsplit(s.video_url).hostname or "", uid=f"{uid}.video",
                      alias=callsign, protocol=urlsplit(s.video_url).scheme or "rtsp",
                      port=str(urlsplit(s.video_url).port or 554), path=urlsplit(s.video_url).path or "/")  # fmt: skip
    out.append(vehicle)
    if s.target is not None:
        g = s.target
        spi = _event(f"{uid}.SPI", "b-m-p-s-p-i", g.lat_deg, g.lon_deg, g.alt_m, g.error_m, t, "m-c")
        d = spi.find("detail")
        assert d is not None
        ET.SubElement(d, "contact", callsign=f"{callsign} SPI")
        ET.SubElement(d, "link", uid=uid, type="a-f-A-M-F-Q", relation="p-p")
        ET.SubElement(
            d, "remarks"
        ).text = f"source {g.source}, error {g.error_m:.1f} m (1 sigma), range {g.range_m:.1f} m"
        ET.SubElement(d, "precisionlocation", geopointsrc=g.source, altsrc="DTED0" if "terrain" in g.source else "???")
        out.append(spi)
    if s.corners and all(c is not None for c in s.corners):
        cs = [c for c in s.corners if c is not None]
        clat = sum(c.lat_deg for c in cs) / 4
        clon = sum(c.lon_deg for c in cs) / 4
        shape = _event(f"{uid}.footprint", "u-d-f", clat, clon, sum(c.alt_m for c in cs) / 4, 9999999.0, t, "h-e")
        d = shape.find("detail")
        assert d is not None
        for c in [*cs, cs[0]]:
            ET.SubElement(d, "link", point=f"{_f(c.lat_deg)},{_f(c.lon_deg)},{c.alt_m:.1f}")
        ET.SubElement(d, "contact", callsign=f"{callsign} footprint")
        ET.SubElement(d, "strokeColor", value="-256")
        ET.SubElement(d, "strokeWeight", value="2.0")
        ET.SubElement(d, "labels_on", value="false")
        out.append(shape)
    return [b'<?xml version="1.0" encoding="UTF-8"?>\n' + ET.tostring(e) for e in out]


class CotSender:
    """Sends `sighting()`'s events to one UDP address at COT_HZ (nothing when it returns None)."""

    def __init__(
        self, url: str, sighting: Callable[[], Sighting | None], *, uid: str, callsign: str, rate_hz: float = COT_HZ
    ) -> None:
        self.address = parse_target(url)
        self.sighting = sighting
        self.uid, self.callsign = uid, callsign
        self.period_s = 1.0 / rate_hz
        self.sent = 0
        try:
            import pytak  # noqa: F401 - fail at start, not at the first second
        except ImportError as e:  # pragma: no cover - depends on the installation
            raise CotConfigError("--cot needs pytak: pip install 'topgimbal[cot]'") from e

    async def run(self) -> None:
        sock = socket.socket(socket.AF_INET6 if ":" in self.address[0] else socket.AF_INET, socket.SOCK_DGRAM)
        sock.setblocking(False)
        if self.address[0].startswith("239."):
            sock.setsockopt(socket.IPPROTO_IP, socket.IP_MULTICAST_TTL, 1)  # TAK's mesh stays on the LAN
        waiting = False  # said once: nothing goes out until the autopilot's position and heading are heard
        try:
            while True:
                try:
                    s = self.sighting()
                    if s is None and not waiting:
                        log.info("CoT %s: no vehicle position and heading (or camera attitude) yet: sending nothing",
                                 self.uid)  # fmt: skip
                    elif s is not None and waiting:
                        log.info("CoT %s: sending to %s:%d", self.uid, *self.address)
                    waiting = s is None
                    if s is not None:
                        for data in events(s, uid=self.uid, callsign=self.callsign):
                            with contextlib.suppress(BlockingIOError):  # a full buffer drops one update
                                sock.sendto(data[:MAX_DATAGRAM], self.address)
                                self.sent += 1
                except OSError as exc:  # unreachable network: say so once a while, keep going
                    log.info("CoT to %s:%d: %s", *self.address, exc)
                await asyncio.sleep(self.period_s)
        finally:
            sock.close()
