"""Valid frames real clients and devices send, gathered from public sources (issue 26, item 1).

Each entry is (source, frame text or bytes): the frames are written here in our own words from
what the sources send, byte for byte where they print a frame (checksum added by `frames()`).
The share of these that `decode_any` decodes with meaning is the figure the issue asks for
(`meaning_share`; `bench/decode_failures.py` prints it and what the others cost to decode).

Sources:
- ARDUPILOT_TOPOTEK: ArduPilot's AP_Mount_Topotek driver (its "sample command" comments and what
  it sends at 1-10 Hz: attitude, SD card, tracking, version, model name, position, zoom, focus).
- GROUND_STATION: a public SkyDroid C13 ground station (Python library and its Qt port): digital
  zoom as image code + `F` + three hex digits in 0.1x ("PROTOCAL §14.1", e.g. 14x ->
  `#tpPD6wDZM00F08C84`, image codes beyond 00/01 sent as given), `#TPUD2wSLR015B` to fire one
  laser measurement before reading it (to D and to the laser module E), MUL optical zoom, pod
  addressing (P -> M / D).
- DEVICES: replies quoted in the seeds README (public reports of real units).
"""

from __future__ import annotations

from topgimbal.protocol import Frame, decode_any, parse_frame

ARDUPILOT_TOPOTEK = "ArduPilot AP_Mount_Topotek"
GROUND_STATION = "public SkyDroid C13 ground station (Python + Qt)"
DEVICES = "real devices (seeds README)"


def with_crc(text: str | bytes) -> bytes:
    raw = text.encode("latin-1") if isinstance(text, str) else text
    return raw + b"%02X" % (sum(raw) % 256)


def _s16(v: int) -> str:
    return f"{v & 0xFFFF:04X}"


def _ardupilot() -> list[bytes]:
    out = [
        "#TPUD2wCAP01", "#TPUD2wREC01", "#TPUD2wREC00", "#TPUM2wZMC00", "#TPUM2wZMC01", "#TPUM2wZMC02",
        "#TPUM2wFCC00", "#TPUM2wFCC01", "#TPUM2wFCC02", "#TPUM2wFCC10", "#TPUM2wFCC11", "#TPUD2wTRC01",
        "#TPUD2wTRC02", "#TPUD2rTRC00", "#TPUG2wGIA01", "#TPUD2rSDC00", "#TPUD2rSDC01", "#TPUD2rVSN00",
        "#TPUD2rPA200", "#TPUG2wPTZ05", "#TPUG2wPTZ06", "#TPUG2wPTZ07", "#TPUG2wPTZ0A", "#TPUD2wPIP0A",
        "#TPUD2wLRF02", "#TPUD2wIRC0A",
    ]  # fmt: skip
    frames = [with_crc(t) for t in out]
    for yaw, pitch, roll in ((10, -20, 0), (-99, 99, 5), (0, 0, 0)):
        frames.append(with_crc(f"#tpUG6wYPR{yaw & 0xFF:02X}{pitch & 0xFF:02X}{roll & 0xFF:02X}"))
    for ident, deg in (("GIY", 30.0), ("GAY", -120.0), ("GIP", 45.0), ("GIR", 0.0)):
        frames.append(with_crc(f"#tpUG6w{ident}{_s16(round(deg * 100))}32"))
    # tracking box: centre x, y, width, height as big-endian int16, then 0 and 9 (point) / 1 (box)
    box = b"".join(v.to_bytes(2, "big", signed=True) for v in (120, -80, 62, 111)) + bytes([0, 9])
    frames.append(with_crc(b"#tpUDAwLOC" + box))
    frames += [
        with_crc("#tpUDBwLATN2232.6543"), with_crc("#tpUDCwLONE11354.1234"),
        with_crc("#tpUD8wALT000123.4"), with_crc("#tpUD5wAZI123.4"), with_crc("#tpUDCwUTC123456261126"),
    ]  # fmt: skip
    return frames


def _ground_station() -> list[bytes]:
    frames: list[bytes] = []
    for zoom_x in (1.0, 2.5, 14.0, 30.0):
        units = round(zoom_x * 10)
        for image in (0, 1, 3):
            frames.append(with_crc(f"#tpPD6wDZM{image:02X}F{units:03X}"))
        frames.append(with_crc(f"#tpUD6wDZM00F{units:03X}"))
        frames.append(with_crc(f"#tpPM4wMUL{units:04d}"))
    frames += [with_crc(f"#tpPD4wDZM00{code}") for code in ("0C", "0D", "0E")]
    frames += [
        with_crc(t)
        for t in (
            "#TPUD2rSLR00", "#TPUD2wSLR01", "#TPUE2wSLR01", "#TPUE2rSLR00", "#TPUG2rGAC00", "#TPUG2wGAA05",
            "#tpUG4wGSM0000", "#TPUG2wGSY0A", "#TPUG2wPTZ01", "#TPUG2wPTZ00", "#tpPM2wZMC02", "#tpPM2wFCC10",
            "#TPUD2wCAP01", "#TPUD2wREC01", "#tpUG8wGOT02800168", "#TPUG2wSUM01", "#TPUG2wSUM00",
            "#tpUD4wIMG0102", f"#tpUG6wGAY{_s16(-2085)}1E", f"#tpUG6wGAP{_s16(-2531)}1E",
            f"#tpUGCwGAM{_s16(3000)}FA{_s16(-4500)}C8",
        )
    ]  # fmt: skip
    return frames


def _devices() -> list[bytes]:
    return [
        b"#tpGPCrGACFF36ED5A0048DE",
        b"#tpDU3rVER0105025A",
        with_crc("#TPDU4rSLR0140"),
        with_crc("#TPDU4rSLR0208"),
        with_crc("#TPDU2rTRC02"),
        with_crc("#tpMU7wLRF12345.6"),
        with_crc("#tpMU3wLRFERR"),
        with_crc("#tpDU5rVSN1.2.3"),
        with_crc(f"#tpGUCrGIA{_s16(1234)}{_s16(-567)}{_s16(12)}"),
    ]


SOURCES = {ARDUPILOT_TOPOTEK: _ardupilot, GROUND_STATION: _ground_station, DEVICES: _devices}


def frames() -> list[tuple[str, Frame]]:
    """Every corpus frame, parsed (each is a valid frame: checksum and length check out)."""
    return [(source, parse_frame(raw)) for source, make in SOURCES.items() for raw in make()]


def has_meaning(frame: Frame) -> bool:
    """Decoded by some dialect by a form of the catalog: a query, or fields of which at least one
    is more than raw bytes of an undocumented layout."""
    msg = decode_any(frame)
    if msg.fields is None or msg.form is None:
        return False
    fields = msg.form.fields
    return not fields or any(f.codec.kind != "raw" for f in fields)


def without_meaning() -> list[tuple[str, Frame]]:
    return [(source, f) for source, f in frames() if not has_meaning(f)]


def meaning_share() -> float:
    every = frames()
    return sum(has_meaning(f) for _s, f in every) / len(every)
