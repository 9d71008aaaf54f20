"""MISB ST 0601 (UAS Datalink Local Set) packets: the metadata a KLV-aware player (QGIS FMV,
Esri, ATAK, klvdata) puts on a map next to the video. Pure: values in user units in, bytes out.

Each value is mapped onto its tag's integer range as ST 0601 defines it (IMAPA-free "legacy"
mappings: value / range * (2^n - 1)); a value outside its tag's range, or unknown (None, NaN), is
left out of the packet. Tag 2 (the precision time stamp) comes first and tag 1 (the checksum) last,
as the standard requires."""

from __future__ import annotations

import math
import struct
from collections.abc import Mapping

UAS_LS_KEY = bytes.fromhex("060E2B34020B01010E01030101000000")
LS_VERSION = 17  # ST 0601.17

# tag -> (struct format, lo, hi, signed scaling) : value v maps to round(v' / span * full)
_MAP: dict[int, tuple[str, float, float]] = {
    5: (">H", 0.0, 360.0),  # platform heading
    6: (">h", -20.0, 20.0),  # platform pitch
    7: (">h", -50.0, 50.0),  # platform roll
    13: (">i", -90.0, 90.0),  # sensor latitude
    14: (">i", -180.0, 180.0),  # sensor longitude
    15: (">H", -900.0, 19000.0),  # sensor true altitude (m MSL)
    16: (">H", 0.0, 180.0),  # sensor horizontal field of view
    17: (">H", 0.0, 180.0),  # sensor vertical field of view
    18: (">I", 0.0, 360.0),  # sensor relative azimuth
    19: (">i", -180.0, 180.0),  # sensor relative elevation
    20: (">I", 0.0, 360.0),  # sensor relative roll
    21: (">I", 0.0, 5_000_000.0),  # slant range (m)
    23: (">i", -90.0, 90.0),  # frame centre latitude
    24: (">i", -180.0, 180.0),  # frame centre longitude
    25: (">H", -900.0, 19000.0),  # frame centre elevation (m MSL)
}
TAGS = (2, *sorted(_MAP), 65, 1)


def _ber_length(n: int) -> bytes:
    if n < 128:
        return bytes([n])
    body = n.to_bytes((n.bit_length() + 7) // 8, "big")
    return bytes([0x80 | len(body)]) + body


def encode_value(tag: int, value: float) -> bytes | None:
    """The tag's bytes for `value`, or None when it is unknown or outside the tag's range."""
    fmt, lo, hi = _MAP[tag]
    if value is None or not math.isfinite(value) or not lo <= value <= hi:
        return None
    size = struct.calcsize(fmt)
    if fmt[1].islower():  # signed, symmetric about 0: +-(2^(n-1) - 1)
        full = 2 ** (8 * size - 1) - 1
        return struct.pack(fmt, round(value / hi * full))
    full = 2 ** (8 * size) - 1
    return struct.pack(fmt, round((value - lo) / (hi - lo) * full))


def checksum(data: bytes) -> int:
    """ST 0601's running 16-bit sum: bytes alternately as the high and the low byte."""
    bcc = 0
    for i, b in enumerate(data):
        bcc += b << (8 * ((i + 1) % 2))
    return bcc & 0xFFFF


def packet(timestamp_us: int, values: Mapping[int, float | None]) -> bytes:
    """One UAS Datalink LS packet: tag 2 (`timestamp_us`, microseconds since 1970 UTC), the given
    tags that are known and in range, tag 65 (the LS version), tag 1 (the checksum)."""
    body = bytearray(b"\x02\x08" + struct.pack(">Q", timestamp_us))
    for tag in sorted(values):
        if tag not in _MAP:
            raise ValueError(f"ST 0601 tag {tag} is not one this encoder writes ({sorted(_MAP)})")
        raw = encode_value(tag, values[tag])  # type: ignore[arg-type]
        if raw is not None:
            body += bytes([tag, len(raw)]) + raw
    body += bytes([65, 1, LS_VERSION])
    body += b"\x01\x02"  # the checksum's tag and length are summed too
    head = UAS_LS_KEY + _ber_length(len(body) + 2)
    crc = checksum(head + bytes(body))
    return head + bytes(body) + struct.pack(">H", crc)
