"""EXIF and XMP for photos: what the camera was fed (position, time) and its pose, in the tags
mapping tools read; written into a JPEG without re-encoding it.

EXIF (built with Pillow's `Image.Exif`): Make, Model, DateTimeOriginal (the camera's clock, with
SubSecTimeOriginal for the fraction of its second),
FocalLength / FocalLengthIn35mmFilm / DigitalZoomRatio, and the GPS IFD (latitude, longitude,
altitude above sea level). XMP (our own small packet): DJI's `drone-dji` namespace
(GimbalYaw/Pitch/RollDegree, FlightYaw/Pitch/RollDegree, AbsoluteAltitude), which exiftool,
Pix4D and OpenDroneMap read, and Pix4D's `Camera` namespace (Camera:Yaw / Pitch / Roll, with
Pix4D's pitch 0 = nadir, so Camera:Pitch = gimbal pitch + 90).

`splice()` replaces the APP1 Exif and APP1 XMP segments of a JPEG byte string and keeps every
other byte (the picture is not decoded): what the geotag tool uses to tag existing files."""

from __future__ import annotations

import datetime
import math
from collections.abc import MutableMapping
from dataclasses import dataclass
from fractions import Fraction
from typing import Any

from PIL import Image
from PIL.TiffImagePlugin import IFDRational

from ..geo.earth import wrap360

EXIF_HEADER = b"Exif\x00\x00"
XMP_HEADER = b"http://ns.adobe.com/xap/1.0/\x00"
MAX_SEGMENT_BYTES = 65533  # an APP segment's payload (length field 16 bits, itself included)

IFD_EXIF, IFD_GPS = 0x8769, 0x8825
TAG_MAKE, TAG_MODEL, TAG_DATETIME = 0x010F, 0x0110, 0x0132
TAG_ORIGINAL, TAG_FOCAL, TAG_ZOOM, TAG_FOCAL_35 = 0x9003, 0x920A, 0xA404, 0xA405
TAG_SUBSEC, TAG_SUBSEC_ORIGINAL = 0x9290, 0x9291  # the fraction of DateTime / DateTimeOriginal's second
EXIF_TIME = "%Y:%m:%d %H:%M:%S"


class ExifError(ValueError):
    """A file that is not a JPEG we can tag (truncated, not JPEG, segment too long)."""


@dataclass(frozen=True)
class Pose:
    yaw_deg: float
    pitch_deg: float
    roll_deg: float


@dataclass(frozen=True)
class PhotoMeta:
    make: str = ""
    model: str = ""
    time: datetime.datetime | None = None  # the camera's clock (naive, as cameras write it)
    lat_deg: float | None = None
    lon_deg: float | None = None
    alt_m: float | None = None  # above mean sea level
    focal_mm: float | None = None
    focal_35mm: int | None = None
    zoom_x: float | None = None  # digital zoom ratio
    gimbal: Pose | None = None  # earth frame: yaw true north, pitch up-positive, roll right-positive
    flight: Pose | None = None  # the vehicle's attitude
    width_px: int | None = None
    height_px: int | None = None

    @property
    def has_position(self) -> bool:
        return self.lat_deg is not None and self.lon_deg is not None


def _dms(value_deg: float) -> tuple[IFDRational, IFDRational, IFDRational]:
    """Degrees, minutes, seconds (1e-4 s: 3 mm of latitude)."""
    v = abs(value_deg)
    d = int(v)
    m = int((v - d) * 60)
    s = round(((v - d) * 60 - m) * 60 * 10000)
    if s >= 600000:  # rounding reached a full minute
        s, m = 0, m + 1
    if m >= 60:
        m, d = 0, d + 1
    return IFDRational(d, 1), IFDRational(m, 1), IFDRational(s, 10000)


def _rational(value: float, denominator: int = 1000) -> IFDRational:
    f = Fraction(round(value * denominator), denominator)
    return IFDRational(f.numerator, f.denominator)


def build_exif(meta: PhotoMeta, base: Image.Exif | None = None) -> Image.Exif:
    """`meta` as EXIF, on top of `base` (tags of an existing file) when given; None parts of `meta`
    leave `base`'s tags as they are."""
    exif = base if base is not None else Image.Exif()
    if meta.make:
        exif[TAG_MAKE] = meta.make
    if meta.model:
        exif[TAG_MODEL] = meta.model
    sub = exif.get_ifd(IFD_EXIF)
    # The tags EXIF 2.32 requires of a JPEG (exiftool -validate), where the file has none yet.
    required: tuple[tuple[MutableMapping[int, Any], int, object], ...] = (
        (exif, 0x011A, IFDRational(72, 1)),  # XResolution
        (exif, 0x011B, IFDRational(72, 1)),  # YResolution
        (exif, 0x0128, 2),  # ResolutionUnit: inch
        (exif, 0x0213, 1),  # YCbCrPositioning: centred
        (sub, 0x9000, b"0232"),  # ExifVersion
        (sub, 0x9101, b"\x01\x02\x03\x00"),  # ComponentsConfiguration: Y Cb Cr
        (sub, 0xA000, b"0100"),  # FlashpixVersion
        (sub, 0xA001, 1),  # ColorSpace: sRGB
    )
    for ifd, tag, value in required:
        ifd.setdefault(tag, value)
    if meta.width_px is not None and meta.height_px is not None:
        sub[0xA002], sub[0xA003] = int(meta.width_px), int(meta.height_px)
    if meta.time is not None:
        # EXIF cuts the time to whole seconds and keeps the fraction apart (SubSecTimeOriginal,
        # hundredths here): a reader that adds them gets the camera's clock, not up to 1 s before it.
        exif[TAG_DATETIME] = sub[TAG_ORIGINAL] = meta.time.strftime(EXIF_TIME)
        sub[TAG_SUBSEC] = sub[TAG_SUBSEC_ORIGINAL] = f"{meta.time.microsecond // 10_000:02d}"
    if meta.focal_mm is not None:
        sub[TAG_FOCAL] = _rational(meta.focal_mm, 100)
    if meta.focal_35mm is not None:
        sub[TAG_FOCAL_35] = int(meta.focal_35mm)
    if meta.zoom_x is not None:
        sub[TAG_ZOOM] = _rational(meta.zoom_x, 100)
    if meta.has_position:
        assert meta.lat_deg is not None and meta.lon_deg is not None
        gps = exif.get_ifd(IFD_GPS)
        gps[0] = b"\x02\x03\x00\x00"  # GPSVersionID 2.3
        gps[1] = "N" if meta.lat_deg >= 0 else "S"
        gps[2] = _dms(meta.lat_deg)
        gps[3] = "E" if meta.lon_deg >= 0 else "W"
        gps[4] = _dms(meta.lon_deg)
        if meta.alt_m is not None:
            gps[5] = b"\x00" if meta.alt_m >= 0 else b"\x01"  # above / below sea level
            gps[6] = _rational(abs(meta.alt_m), 1000)
        gps[18] = "WGS-84"  # GPSMapDatum
    return exif


def xmp_packet(meta: PhotoMeta) -> bytes | None:
    """The gimbal and vehicle pose as an XMP packet (None when `meta` has no pose)."""
    attrs: list[str] = []

    def add(name: str, value: float) -> None:
        attrs.append(f'{name}="{value:+.2f}"')

    if meta.gimbal is not None:
        g = meta.gimbal
        add("drone-dji:GimbalYawDegree", g.yaw_deg)
        add("drone-dji:GimbalPitchDegree", g.pitch_deg)
        add("drone-dji:GimbalRollDegree", g.roll_deg)
        add("Camera:Yaw", wrap360(g.yaw_deg))
        add("Camera:Pitch", g.pitch_deg + 90.0)  # Pix4D: 0 = nadir
        add("Camera:Roll", g.roll_deg)
    if meta.flight is not None:
        f = meta.flight
        add("drone-dji:FlightYawDegree", f.yaw_deg)
        add("drone-dji:FlightPitchDegree", f.pitch_deg)
        add("drone-dji:FlightRollDegree", f.roll_deg)
    if meta.alt_m is not None and meta.has_position:
        add("drone-dji:AbsoluteAltitude", meta.alt_m)
    if not attrs:
        return None
    body = "\n    ".join(attrs)
    text = (
        '<?xpacket begin="\ufeff" id="W5M0MpCehiHzreSzNTczkc9d"?>\n'
        '<x:xmpmeta xmlns:x="adobe:ns:meta/">\n'
        ' <rdf:RDF xmlns:rdf="http://www.w3.org/1999/02/22-rdf-syntax-ns#">\n'
        '  <rdf:Description rdf:about=""\n'
        '    xmlns:drone-dji="http://www.dji.com/drone-dji/1.0/"\n'
        '    xmlns:Camera="http://pix4d.com/camera/1.0/"\n'
        f"    {body}/>\n"
        " </rdf:RDF>\n"
        "</x:xmpmeta>\n"
        '<?xpacket end="w"?>'
    )
    return text.encode("utf-8")


def _segment(marker: int, payload: bytes) -> bytes:
    if len(payload) > MAX_SEGMENT_BYTES:
        raise ExifError(f"metadata segment too long ({len(payload)} bytes, at most {MAX_SEGMENT_BYTES})")
    return bytes((0xFF, marker)) + (len(payload) + 2).to_bytes(2, "big") + payload


def segments(jpeg: bytes) -> tuple[list[tuple[int, bytes]], bytes]:
    """The marker segments before the scan ([(marker, payload)]), and the rest from SOS on."""
    if not jpeg.startswith(b"\xff\xd8"):
        raise ExifError("not a JPEG (no SOI marker)")
    out: list[tuple[int, bytes]] = []
    i = 2
    while True:
        if i + 4 > len(jpeg) or jpeg[i] != 0xFF:
            raise ExifError(f"truncated or damaged JPEG (byte {i})")
        marker = jpeg[i + 1]
        if marker == 0xDA:  # start of scan: the picture follows
            return out, jpeg[i:]
        length = int.from_bytes(jpeg[i + 2 : i + 4], "big")
        if length < 2 or i + 2 + length > len(jpeg):
            raise ExifError(f"truncated JPEG segment at byte {i}")
        out.append((marker, jpeg[i + 4 : i + 2 + length]))
        i += 2 + length


def splice(jpeg: bytes, exif: bytes | None, xmp: bytes | None) -> bytes:
    """`jpeg` with its APP1 Exif replaced by `exif` and its APP1 XMP by `xmp` (None: kept)."""
    segs, rest = segments(jpeg)
    kept: list[tuple[int, bytes]] = []
    for marker, payload in segs:
        if marker == 0xE1 and exif is not None and payload.startswith(EXIF_HEADER):
            continue
        if marker == 0xE1 and xmp is not None and payload.startswith(XMP_HEADER):
            continue
        kept.append((marker, payload))
    head = [s for s in kept if s[0] == 0xE0]  # JFIF stays first
    new: list[tuple[int, bytes]] = []
    if exif is not None:
        new.append((0xE1, exif if exif.startswith(EXIF_HEADER) else EXIF_HEADER + exif))
    if xmp is not None:
        new.append((0xE1, XMP_HEADER + xmp))
    ordered = head + new + [s for s in kept if s[0] != 0xE0]
    return b"\xff\xd8" + b"".join(_segment(m, p) for m, p in ordered) + rest


def tag_jpeg(jpeg: bytes, meta: PhotoMeta, base: Image.Exif | None = None) -> bytes:
    return splice(jpeg, build_exif(meta, base).tobytes(), xmp_packet(meta))


def focal_lengths(hfov_deg: float, zoom_x: float, sensor_width_mm: float) -> tuple[float, int]:
    """Focal length (mm) and its 35 mm equivalent for a horizontal field of view at 1x."""
    half = math.tan(math.radians(hfov_deg) / 2.0)
    return sensor_width_mm / 2.0 / half * zoom_x, round(36.0 / 2.0 / half * zoom_x)
