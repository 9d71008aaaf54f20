"""Golden tests: every literal example frame of both vendor documents.

The table below holds every complete example frame of SkyDroid "TOP 协议" V1.1.5 (`skydroid`) and
TOPOTEK "Udp&uart-Protocol" V1.1.3 (`topotek`), in document order, with what the document says the
frame means (expected field values in user units). Templates with placeholders (`X0X1…RR`,
`xxxxxxxx`, `VX.X.X`, frames with spaced-out placeholders) are left out. Every checksum in the table
was verified independently (`sum(body) % 256`); the frames whose checksum or length is wrong in the
documents are tested one by one further down, asserting exactly what is wrong.

The 192.168.x.x strings are IP *settings* carried inside frames: test data only, nothing is sent.
"""

from __future__ import annotations

import re
from datetime import datetime
from pathlib import Path
from typing import Any, NamedTuple

import pytest

from topgimbal.errors import ChecksumError, FrameError
from topgimbal.protocol import (
    REQUEST,
    RESPONSE,
    Diagnostic,
    Frame,
    FrameParser,
    checksum,
    direction_of,
    dissect,
    get_dialect,
    make_frame,
    parse_frame,
)

pytestmark = pytest.mark.virtual

VALID = "valid"  # checks out and decodes as it stands
# A reply example whose source and destination are NOT swapped (the document's mistake): the frame
# itself checks out; its meaning is asserted on the swapped frame, as a device would send it.
REPLY_UNSWAPPED = "reply-unswapped"
# TOPOTEK's appendix checksum example uses AWB, an identifier the TOPOTEK document never defines.
FRAME_ONLY = "frame-only"


class E(NamedTuple):
    doc: str
    section: str
    text: str
    expect: str
    fields: dict[str, Any] | None


# fmt: off
EXAMPLES: list[E] = [
    E("skydroid", "§2.3.2", "#TPMU2wERE!!30", VALID, {"error": "!!"}),
    E("skydroid", "§3.1", "#TPUG2wPTZ006A", VALID, {"action": "stop"}),
    E("skydroid", "§3.2", "#TPUG2wGSYE276", VALID, {"yaw_rate_deg_s": -3.0}),
    E("skydroid", "§3.3.2.2", "#TPUG2wGAA0136", VALID, {"rate_hz": 1}),
    E("skydroid", "§3.3.4", "#TPUG2wSUM0061", VALID, {"action": "stop"}),
    E("skydroid", "§3.3.4", "#TPUG2wSUM0162", VALID, {"action": "confirm"}),
    E("skydroid", "§3.3.6.1", "#TPUG2wFAE0139", VALID, {"state": "on"}),
    E("skydroid", "§4.1.1", "#TPUD2wREC0A54", VALID, {"action": "toggle"}),
    E("skydroid", "§4.1.2", "#TPUD2rREC003E", VALID, {}),
    E("skydroid", "§4.2", "#TPUD2wCAP013E", VALID, {"mode": "photo"}),
    E("skydroid", "§4.3.1", "#TPUD2wVID004C", VALID, {"secondary": "720p", "primary": "720p"}),
    E("skydroid", "§4.3.2", "#TPUD2rVID0047", VALID, {}),
    E("skydroid", "§4.4", "#TPUD2rSDC003E", VALID, {}),
    E("skydroid", "§4.5.1.1", "#TPUD2wAWB0043", VALID, {"secondary": "auto", "primary": "auto"}),
    E("skydroid", "§4.5.1.2", "#TPUD2rAWB003E", VALID, {}),
    E("skydroid", "§4.5.2.1 set", "#TPUDCwIQE007F7F7F7F7FCA", VALID, {"lens": 0, "style": "custom", "hue": 127, "brightness": 127, "saturation": 127, "contrast": 127, "sharpness": 127}),
    E("skydroid", "§4.5.2.1 read", "#TPUD2rIQE0043", VALID, {}),
    E("skydroid", "§4.6", "#tpUDFwTIM142832.0003121838", VALID, {"time": datetime(2018, 12, 3, 14, 28, 32)}),
    E("skydroid", "§4.7.1", "#TPUD2wDZM0A65", VALID, {"zoom": "zoom_in"}),
    E("skydroid", "§4.7.1", "#TPUD2wDZM0B66", VALID, {"zoom": "zoom_out"}),
    E("skydroid", "§4.7.2", "#TPUD2rDZM004F", VALID, {}),
    E("skydroid", "§4.8.1", "#TPUD2wIMG0A57", VALID, {"palette": "medical"}),
    E("skydroid", "§4.8.2", "#TPUD2rIMG0041", VALID, {}),
    E("skydroid", "§4.9.1.1", "#tpUD2rIPV0093", VALID, {}),
    E("skydroid", "§4.9.1.1 reply", "#tpUDDrIPV192.168.31.22D2", REPLY_UNSWAPPED, {"address": "192.168.31.22"}),
    E("skydroid", "§4.9.1.2", "#tpUDDwIPV192.168.31.22D7", VALID, {"address": "192.168.31.22"}),
    E("skydroid", "§4.9.2.1", "#tpUD2rGTW0096", VALID, {}),
    E("skydroid", "§4.9.2.1 reply", "#tpUDCrGTW192.168.31.1A1", REPLY_UNSWAPPED, {"address": "192.168.31.1"}),
    E("skydroid", "§4.9.2.2", "#tpUDCwGTW192.168.31.1A6", VALID, {"address": "192.168.31.1"}),
    E("skydroid", "§4.9 table", "#tpUDDwIPV192.168.31.22D7", VALID, {"address": "192.168.31.22"}),
    E("skydroid", "§4.9 table", "#tpUDCwGTW192.168.31.1A6", VALID, {"address": "192.168.31.1"}),
    E("skydroid", "§4.9 table", "#tpUDDwDNS114.114.114.4C0", VALID, {"address": "114.114.114.4"}),
    E("skydroid", "§4.9 table", "#tpUDDwBNS114.114.114.4BE", VALID, {"address": "114.114.114.4"}),
    E("skydroid", "§4.10.1 read", "#TPUD2rVOM0056", VALID, {}),
    E("skydroid", "§4.10.1 read reply", "#tpDUBrVOM111E1E0400189", VALID, {"h_flip": "on", "v_flip": "on", "fps": 30, "gop": 30, "bitrate_kbps": 1024, "output": "on"}),
    E("skydroid", "§4.11", "#TPUD2rVER0051", VALID, {}),
    E("skydroid", "§4.11 reply", "#tpDU6rVERV1.0.078", VALID, {"version": "V1.0.0"}),
    E("skydroid", "§4.12.1", "#tpUD4wEXT0000FC", VALID, {"reserved": "zero", "dish_calibration": "off", "osd": "off", "led": "off"}),
    E("skydroid", "§4.12.2", "#TPUD2rEXT0055", VALID, {}),
    E("skydroid", "§4.13.1", "#tpUD8wUID00000001B2", VALID, {"uid": 1}),
    E("skydroid", "§4.13.2", "#TPUD2rUID0046", VALID, {}),
    # §4.13.2 gives the §4.13.1 *set* command as its reply example (see test_skydroid_uid_reply_example).
    E("skydroid", "§4.13.2 reply", "#tpUD8wUID00000001B2", VALID, {"uid": 1}),
    E("skydroid", "§4.14.1", "#TPUD2wTSM005D", VALID, {"scene": "general"}),
    E("skydroid", "§4.14.2", "#TPUD2rTSM0058", VALID, {}),
    E("skydroid", "§4.15.1", "#TPUD2wTAS0556", VALID, {"interval_s": 5}),
    E("skydroid", "§4.15.2", "#TPUD2rTAS004C", VALID, {}),
    E("skydroid", "§4.16.1", "#TPUD2wTDI004A", VALID, {"detail": 0}),
    E("skydroid", "§4.16.2", "#TPUD2rTDI0045", VALID, {}),
    E("skydroid", "§4.17.1", "#TPUD2wTIB0048", VALID, {"brightness": 0}),
    E("skydroid", "§4.17.2", "#TPUD2rTIB0043", VALID, {}),
    E("skydroid", "§4.18.1", "#TPUD2wTIC0049", VALID, {"contrast": 0}),
    E("skydroid", "§4.18.2", "#TPUD2rTIC0044", VALID, {}),
    E("skydroid", "§4.19.1", "#TPUD2wTAR0050", VALID, {"spatial_denoise": 0}),
    E("skydroid", "§4.19.2", "#TPUD2rTAR004B", VALID, {}),
    E("skydroid", "§4.20.1", "#TPUD2wTTR0063", VALID, {"temporal_denoise": 0}),
    E("skydroid", "§4.20.2", "#TPUD2rTTR005E", VALID, {}),
    E("skydroid", "§4.21.1", "#TPUD2wTGM0051", VALID, {"gamma": 0}),
    E("skydroid", "§4.21.2", "#TPUD2rTGM004C", VALID, {}),
    E("skydroid", "§4.22.1", "#TPUD2rSLR0055", VALID, {}),
    # §4.22.1 reply: #TP with length 4 and addresses not swapped (see test_skydroid_slr_reply_example).
    E("skydroid", "§4.22.1 reply", "#TPUD4rSLR0005BC", REPLY_UNSWAPPED, {"distance_m": 0.5}),
    E("skydroid", "Appendix II", "#TPUD2wAWB0144", VALID, {"secondary": "auto", "primary": "night"}),
    E("topotek", "§三.1.1 uart", "#tpUM2wZMC009C", VALID, {"action": "stop"}),
    E("topotek", "§三.1.1 uart", "#tpUM2wZMC019D", VALID, {"action": "zoom_out"}),
    E("topotek", "§三.1.1 uart", "#tpUM2wZMC029E", VALID, {"action": "zoom_in"}),
    E("topotek", "§三.1.1 udp", "#tpPM2wZMC0097", VALID, {"action": "stop"}),
    E("topotek", "§三.1.1 udp", "#tpPM2wZMC0198", VALID, {"action": "zoom_out"}),
    E("topotek", "§三.1.1 udp", "#tpPM2wZMC0299", VALID, {"action": "zoom_in"}),
    E("topotek", "§三.1.2 uart", "#tpUM2rZOM00A3", VALID, {}),
    E("topotek", "§三.1.2 udp", "#tpPM2rZOM009E", VALID, {}),
    E("topotek", "§三.1.2 reply", "#tpMU4rZOMFFB447", VALID, {"zoom_pos": -76}),
    E("topotek", "§三.2.1 uart", "#tpUM2wFCC007E", VALID, {"action": "stop"}),
    E("topotek", "§三.2.1 uart", "#tpUM2wFCC017F", VALID, {"action": "focus_plus"}),
    E("topotek", "§三.2.1 uart", "#tpUM2wFCC0280", VALID, {"action": "focus_minus"}),
    E("topotek", "§三.2.1 udp", "#tpPM2wFCC0079", VALID, {"action": "stop"}),
    E("topotek", "§三.2.1 udp", "#tpPM2wFCC017A", VALID, {"action": "focus_plus"}),
    E("topotek", "§三.2.1 udp", "#tpPM2wFCC027B", VALID, {"action": "focus_minus"}),
    E("topotek", "§三.2.2 uart", "#tpUM2rFOC0085", VALID, {}),
    E("topotek", "§三.2.2 udp", "#tpPM2rFOC0080", VALID, {}),
    E("topotek", "§三.2.2 reply", "#tpMU4rFOCFFB429", VALID, {"focus_pos": -76}),
    E("topotek", "§三.3", "#tpUM8wZFPFFB400320F", VALID, {"zoom_pos": -76, "focus_pos": 50}),
    E("topotek", "§三.4", "#tpMU4rZOMFFB447", VALID, {"zoom_pos": -76}),
    E("topotek", "§三.5", "#TPUM2rSWH005F", VALID, {}),
    E("topotek", "§三.6 uart", "#tpUM2wIRC0090", VALID, {"mode": "day"}),
    E("topotek", "§三.6 udp", "#tpPM2wIRC008B", VALID, {"mode": "day"}),
    E("topotek", "§三.7 uart", "#tpUM2wATE008C", VALID, {"state": "off"}),
    E("topotek", "§三.7 udp", "#tpPM2wATE0087", VALID, {"state": "off"}),
    E("topotek", "§三.8 uart", "#tpUM2rVSN00A4", VALID, {}),
    E("topotek", "§三.8 udp", "#tpPM2rVSN009F", VALID, {}),
    E("topotek", "§三.8 reply", "#tpPM5rVSNM33265D", REPLY_UNSWAPPED, {"version": "M3326"}),
    E("topotek", "§三.9.1 uart", "#tpUM4wMUL012308", VALID, {"magnification_x": 12.3}),
    E("topotek", "§三.9.1 udp", "#tpPM4wMUL012303", VALID, {"magnification_x": 12.3}),
    E("topotek", "§三.9.2 uart", "#tpUM2rMUL009B", VALID, {}),
    E("topotek", "§三.9.2 udp", "#tpPM2rMUL0096", VALID, {}),
    E("topotek", "§三.10 uart", "#tpUM2wAPC0086", VALID, {"action": "stop"}),
    E("topotek", "§三.10 uart", "#tpUM2wAPC0187", VALID, {"action": "close"}),
    E("topotek", "§三.10 uart", "#tpUM2wAPC0288", VALID, {"action": "open"}),
    E("topotek", "§三.10 udp", "#tpPM2wAPC0081", VALID, {"action": "stop"}),
    E("topotek", "§三.10 udp", "#tpPM2wAPC0182", VALID, {"action": "close"}),
    E("topotek", "§三.10 udp", "#tpPM2wAPC0283", VALID, {"action": "open"}),
    E("topotek", "§四.1", "#TPUG2wPTZ006A", VALID, {"action": "stop"}),
    # §四.2: the text says 0.1 deg/s, the table deg/s; the dialect defaults to the table (errata E7),
    # so E2 = -30 deg/s here (see test_topotek_speed_unit_option for the text's reading, -3.0).
    E("topotek", "§四.2", "#TPUG2wGSYE276", VALID, {"yaw_rate_deg_s": -30}),
    E("topotek", "§四.3.1", "#tpUG6wGAYEF073288", VALID, {"yaw_deg": -43.45, "speed_deg_s": 5.0}),
    E("topotek", "§四.3.2", "#tpUG6wGIYEF073290", VALID, {"yaw_deg": -43.45, "speed_deg_s": 5.0}),
    E("topotek", "§四.3.3", "#TPUG2rGAC0032", VALID, {}),
    E("topotek", "§四.3.4 set", "#TPUG2wGAA0136", VALID, {"state": "on"}),
    E("topotek", "§四.3.4 read", "#TPUG2rGAA0030", VALID, {}),
    E("topotek", "§四.3.5", "#TPUG2rGIC003A", VALID, {}),
    E("topotek", "§四.3.6 set", "#TPUG2wGIA013E", VALID, {"state": "on"}),
    E("topotek", "§四.3.6 read", "#TPUG2rGIA0038", VALID, {}),
    E("topotek", "§四.4 uart", "#tpUG2wGMS0194", VALID, {"state": "on"}),
    E("topotek", "§四.4 udp", "#tpPG2wGMS018F", VALID, {"state": "on"}),
    E("topotek", "§四.5.1", "#TPUG2rVER0054", VALID, {}),
    E("topotek", "§五.1.1", "#TPUD2wREC0A54", VALID, {"action": "toggle"}),
    E("topotek", "§五.1.2", "#TPUD2rREC003E", VALID, {}),
    E("topotek", "§五.2", "#TPUD2wCAP013E", VALID, {"mode": "visible_thermal"}),
    E("topotek", "§五.3.1", "#TPUD2wVID214F", VALID, {"stream": "rtsp", "resolution": "1920x1080"}),
    E("topotek", "§五.3.2", "#TPUD2rVID0047", VALID, {}),
    E("topotek", "§五.4.1", "#tpPD6wBITK012346C", VALID, {"bitrate_kbps": 1234}),
    E("topotek", "§五.4.2", "#TPUD2rBIT0043", VALID, {}),
    E("topotek", "§五.5", "#TPUD2rSDC003E", VALID, {"which": "remaining"}),
    E("topotek", "§五.6 set", "#TPUD2wROT005E", VALID, {"rotation": "normal"}),
    E("topotek", "§五.6 read", "#TPUD2rROT0059", VALID, {}),
    E("topotek", "§五.7", "#tpUDDwIPV192.168.31.22D7", VALID, {"address": "192.168.31.22"}),
    E("topotek", "§五.7", "#tpUDCwGTW192.168.31.1A6", VALID, {"address": "192.168.31.1"}),
    E("topotek", "§五.7", "#TPUD2wRST0163", VALID, {"action": "reset"}),
    E("topotek", "§五.9", "#TPUM2wLRF0258", VALID, {"action": "single"}),
    E("topotek", "§五.11.1", "#TPUD2wPIP0A63", VALID, {"secondary": "main_only", "mode": "next"}),
    E("topotek", "§五.11.2", "#TPUD2rPIP004D", VALID, {}),
    E("topotek", "§五.12.4 uart", "#tpUD2wTMR009C", VALID, {"range": "low"}),
    E("topotek", "§五.12.4 udp", "#tpPD2wTMR0097", VALID, {"range": "low"}),
    E("topotek", "§五.13.1", "#TPUD2wIMG0A57", VALID, {"palette": "next"}),
    E("topotek", "§五.13.2", "#TPUD2rIMG0041", VALID, {}),
    E("topotek", "§五.14.1", "#tpUD3wDZM00AD6", VALID, {"lens": "visible", "zoom": "step_in"}),
    E("topotek", "§五.14.1", "#tpUD3wDZM10AD7", VALID, {"lens": "thermal", "zoom": "step_in"}),
    E("topotek", "§五.14.2", "#TPUD2rDZM004F", VALID, {}),
    E("topotek", "§五.15.1", "#tpPD3wDFG232AD", VALID, {"mode": "manual", "strength": 50}),
    E("topotek", "§五.15.2", "#TPPD2rDFG0030", VALID, {}),
    E("topotek", "§五.16", "#TPPD2rVSN0056", VALID, {}),
    E("topotek", "§五.17.1", "#TPUD2wENT0050", VALID, {"stream": "stream0", "codec": "h264"}),
    # 附录二: the checksum example, identical to SkyDroid"s appendix; TOPOTEK never defines AWB.
    E("topotek", "附录二", "#TPUD2wAWB0144", FRAME_ONLY, None),
]
# fmt: on

SKYDROID = get_dialect("skydroid")
TOPOTEK = get_dialect("topotek")
# The vendor documents, kept verbatim in the repository (docs/vendor/).
SEEDS = Path(__file__).resolve().parents[2] / "docs" / "vendor"
DOCUMENTS = {"skydroid": "skydroid-top-protocol-v1.1.5.txt", "topotek": "topotek-udp-uart-protocol-v1.1.3.txt"}

# The document frames that do not check out (seeds README), verbatim.
GAY_TP = "#TPUG6wGAYEF073288"  # SkyDroid §3.3.1
GOT_TP = "#TPUG8wGOT02800168D5"  # SkyDroid §3.3.5
FAI_13 = "#TPUGCwFAIEC7800000000064"  # SkyDroid §3.3.6.2
VOM_SET = "#tpUDBwVOM111E1E04001AE"  # SkyDroid §4.10.1
WRONG = {"skydroid": [GAY_TP, GOT_TP, FAI_13, VOM_SET], "topotek": []}


def _id(e: E) -> str:
    return f"{e.doc}-{e.section}-{e.text}"


def _dialect(doc: str) -> Any:
    return SKYDROID if doc == "skydroid" else TOPOTEK


class Parts(NamedTuple):
    header: str
    src: str
    dst: str
    length: int
    rw: str
    ident: str
    data: bytes
    crc: str


def parts(text: str) -> Parts:
    """The frame's parts by plain slicing (an oracle independent of the library)."""
    return Parts(text[:3], text[3], text[4], int(text[5], 16), text[6], text[7:10], text[10:-2].encode(), text[-2:])


def crc_of(body: str | bytes) -> str:
    b = body.encode("latin-1") if isinstance(body, str) else body
    return "%02X" % (sum(b) % 256)


def with_crc(body: str) -> str:
    return body + crc_of(body)


def assert_fields(actual: dict[str, Any] | None, expected: dict[str, Any]) -> None:
    assert actual is not None
    assert set(actual) == set(expected)
    for key, value in expected.items():
        if isinstance(value, float):
            assert actual[key] == pytest.approx(value, abs=1e-9), key
        else:
            assert actual[key] == value, key


def run_parser(stream: bytes, step: int | None = None) -> list[Frame | Diagnostic]:
    p = FrameParser()
    out: list[Frame | Diagnostic] = []
    if step is None:
        out += p.feed(stream)
    else:
        for i in range(0, len(stream), step):
            out += p.feed(stream[i : i + step])
    out += p.flush()
    assert p.buffered == 0
    return out


def frames_of(out: list[Frame | Diagnostic]) -> list[Frame]:
    return [o for o in out if isinstance(o, Frame)]


def diagnostics_of(out: list[Frame | Diagnostic]) -> list[Diagnostic]:
    return [o for o in out if isinstance(o, Diagnostic)]


# -- the table itself -------------------------------------------------------------------------


def test_table_counts() -> None:
    assert sum(e.doc == "skydroid" for e in EXAMPLES) == 61
    assert sum(e.doc == "topotek" for e in EXAMPLES) == 79


@pytest.mark.parametrize("ex", EXAMPLES, ids=_id)
def test_example_checksum_and_length_are_right(ex: E) -> None:
    raw = ex.text.encode("ascii")
    p = parts(ex.text)
    assert p.crc == crc_of(raw[:-2])
    assert checksum(raw[:-2]) == int(p.crc, 16)
    assert p.length == len(p.data)
    assert p.header in ("#TP", "#tp")
    assert p.rw in ("r", "w")


# -- every good frame: envelope --------------------------------------------------------------


@pytest.mark.parametrize("ex", EXAMPLES, ids=_id)
def test_example_dissects_and_round_trips(ex: E) -> None:
    raw = ex.text.encode("ascii")
    p = parts(ex.text)
    d = dissect(raw)
    assert d.ok, d.error
    assert d.error is None and d.anomaly is None
    assert (d.header, d.src, d.dst, d.length, d.rw, d.ident, d.data) == tuple(p)[:7]
    assert d.checksum == d.expected_checksum == p.crc
    assert d.frame == Frame(p.header, p.src, p.dst, p.rw, p.ident, p.data)
    assert d.frame.declared_length is None
    assert d.frame.to_bytes() == raw
    assert bytes(d.frame) == raw
    assert parse_frame(ex.text) == d.frame
    assert parse_frame(raw) == d.frame
    assert dissect(raw + b"\r\n").frame == d.frame
    # the strict reading does not need length recovery
    assert dissect(raw, recover_length=False).frame == d.frame
    # one frame alone through the streaming parser, whole and byte by byte
    for step in (None, 1):
        assert run_parser(raw, step) == [d.frame]


# -- every good frame: meaning ---------------------------------------------------------------


@pytest.mark.parametrize("ex", [e for e in EXAMPLES if e.expect == VALID], ids=_id)
def test_example_decodes(ex: E) -> None:
    assert ex.fields is not None
    frame = parse_frame(ex.text)
    msg = _dialect(ex.doc).decode(frame)
    assert msg.error is None, msg.error
    assert msg.fields is not None
    assert msg.spec is not None and msg.spec.ident == frame.ident
    assert msg.form is not None and msg.form.rw == frame.rw
    assert msg.form.direction == direction_of(frame)
    assert_fields(msg.fields, ex.fields)


@pytest.mark.parametrize("ex", [e for e in EXAMPLES if e.expect == VALID], ids=_id)
def test_typed_encoder_rebuilds_example(ex: E) -> None:
    """The typed encoder, given the documented values and the example's header and addresses,
    produces the document's bytes (requests via encode(), replies via response())."""
    assert ex.fields is not None
    dialect = _dialect(ex.doc)
    frame = parse_frame(ex.text)
    if direction_of(frame) == REQUEST:
        rebuilt = dialect.encode(
            frame.ident, read=frame.rw == "r", src=frame.src, dst=frame.dst, header=frame.header, **ex.fields
        )
    else:
        rebuilt = dialect.response(frame.swapped(data=b"00"), header=frame.header, **ex.fields)
    assert rebuilt.to_bytes() == ex.text.encode("ascii")


@pytest.mark.parametrize("ex", [e for e in EXAMPLES if e.expect == REPLY_UNSWAPPED], ids=_id)
def test_reply_example_with_unswapped_addresses(ex: E) -> None:
    """Document mistake: the reply example keeps the query's source and destination (a device swaps
    them, §2.3.1). The frame checks out; swapped, it decodes to the documented value."""
    assert ex.fields is not None
    dialect = _dialect(ex.doc)
    frame = parse_frame(ex.text)
    assert frame.rw == "r" and frame.data != b"00"
    assert frame.src in "UP" and frame.dst in "MDEG"  # host -> device, as in the query
    assert direction_of(frame) == REQUEST
    # The query the document gives just before has the very same addresses.
    query = EXAMPLES[EXAMPLES.index(ex) - 1]
    assert (parts(query.text).ident, parts(query.text).rw, parts(query.text).data) == (frame.ident, "r", b"00")
    assert (parts(query.text).src, parts(query.text).dst) == (frame.src, frame.dst)
    # As it stands it fits no query form; the decoder falls back to the answer forms (errata E5).
    as_is = dialect.decode(frame)
    assert as_is.error is None, as_is.error
    assert_fields(as_is.fields, ex.fields)
    reply = frame.swapped()
    assert direction_of(reply) == RESPONSE
    msg = dialect.decode(reply)
    assert msg.error is None, msg.error
    assert_fields(msg.fields, ex.fields)
    # ... and that swapped frame is exactly what the typed encoder answers to the query
    answer = dialect.response(parse_frame(query.text), header=frame.header, **ex.fields)
    assert answer.to_bytes() == reply.to_bytes()


def test_topotek_appendix_checksum_example() -> None:
    """TOPOTEK 附录二 uses `#TPUD2wAWB0144` only to show the checksum; AWB is not a TOPOTEK
    command. The bytes are SkyDroid's appendix example, which SkyDroid defines."""
    (ex,) = [e for e in EXAMPLES if e.expect == FRAME_ONLY]
    assert ex.doc == "topotek"
    assert any(e.doc == "skydroid" and e.text == ex.text and e.expect == VALID for e in EXAMPLES)
    assert checksum(b"#TPUD2wAWB01") == 0x44
    assert make_frame("AWB", "01", src="U", dst="D").to_bytes() == b"#TPUD2wAWB0144"
    assert SKYDROID.decode(parse_frame(ex.text)).fields == {"secondary": "auto", "primary": "night"}


# -- the documented worked examples, spelled out ------------------------------------------------


def test_worked_example_gimbal_yaw_angle() -> None:
    # TOPOTEK §四.3.1 Eg:#tpUG6wGAYEF073288: EF07 = -4345 -> -43.45 deg, 0x32 = 50 -> 5.0 deg/s
    msg = TOPOTEK.decode(parse_frame("#tpUG6wGAYEF073288"))
    assert msg.fields == {"yaw_deg": pytest.approx(-43.45), "speed_deg_s": pytest.approx(5.0)}
    assert TOPOTEK.encode("GAY", yaw_deg=-43.45, speed_deg_s=5.0).to_bytes() == b"#tpUG6wGAYEF073288"
    # §四.3.2 the gyro twin
    assert TOPOTEK.encode("GIY", yaw_deg=-43.45, speed_deg_s=5.0).to_bytes() == b"#tpUG6wGIYEF073290"
    # -50 deg is 0xEC78 (both documents' text)
    assert TOPOTEK.encode("GAY", yaw_deg=-50, speed_deg_s=0).data == b"EC7800"


def test_worked_example_speed() -> None:
    # SkyDroid §3.2: "3.0 to the left -> -30 -> 0xE2" (0.1 deg/s per step)
    assert SKYDROID.decode(parse_frame("#TPUG2wGSYE276")).fields == {"yaw_rate_deg_s": pytest.approx(-3.0)}
    assert SKYDROID.encode("GSY", yaw_rate_deg_s=-3.0).to_bytes() == b"#TPUG2wGSYE276"


def test_topotek_speed_unit_option() -> None:
    # TOPOTEK §四.2 worked example (text: 0.1 deg/s) versus its table (deg/s, the default)
    frame = parse_frame("#TPUG2wGSYE276")
    assert TOPOTEK.decode(frame).fields == {"yaw_rate_deg_s": -30}
    text_reading = get_dialect("topotek", speed_unit_deg_s=0.1)
    assert text_reading.decode(frame).fields == {"yaw_rate_deg_s": pytest.approx(-3.0)}
    assert text_reading.encode("GSY", yaw_rate_deg_s=-3.0).to_bytes() == b"#TPUG2wGSYE276"


def test_worked_example_zoom_focus_positions() -> None:
    # TOPOTEK §三.1.2 / §三.2.2 / §三.4: FFB4 -> -76
    assert TOPOTEK.decode(parse_frame("#tpMU4rZOMFFB447")).fields == {"zoom_pos": -76}
    assert TOPOTEK.decode(parse_frame("#tpMU4rFOCFFB429")).fields == {"focus_pos": -76}
    query = parse_frame("#tpUM2rZOM00A3")
    assert TOPOTEK.response(query, zoom_pos=-76).to_bytes() == b"#tpMU4rZOMFFB447"
    # §三.3: zoom -76, focus 50 -> #tpUM8wZFPFFB400320F
    assert TOPOTEK.decode(parse_frame("#tpUM8wZFPFFB400320F")).fields == {"zoom_pos": -76, "focus_pos": 50}
    assert TOPOTEK.encode("ZFP", zoom_pos=-76, focus_pos=50, header="#tp").to_bytes() == b"#tpUM8wZFPFFB400320F"


def test_worked_example_magnification() -> None:
    # TOPOTEK §三.9: 0123 -> 12.3x
    assert TOPOTEK.decode(parse_frame("#tpUM4wMUL012308")).fields == {"magnification_x": pytest.approx(12.3)}
    assert TOPOTEK.encode("MUL", magnification_x=12.3).to_bytes() == b"#tpUM4wMUL012308"
    assert TOPOTEK.encode("MUL", magnification_x=12.3, src="P").to_bytes() == b"#tpPM4wMUL012303"


def test_worked_example_video_output() -> None:
    # SkyDroid §4.10.1 read reply: flips on, 0x1E = 30 fps, gop 30, 0x0400 = 1024 kbps, output on
    msg = SKYDROID.decode(parse_frame("#tpDUBrVOM111E1E0400189"))
    assert msg.fields == {"h_flip": "on", "v_flip": "on", "fps": 30, "gop": 30, "bitrate_kbps": 1024, "output": "on"}


def test_worked_example_bitrate_kbps() -> None:
    # TOPOTEK §五.4.1: K01234 = 1234 kb/s
    assert TOPOTEK.decode(parse_frame("#tpPD6wBITK012346C")).fields == {"bitrate_kbps": 1234}
    assert TOPOTEK.encode("BIT", bitrate_kbps=1234, src="P").to_bytes() == b"#tpPD6wBITK012346C"


def test_worked_example_defog() -> None:
    # TOPOTEK §五.15.1: manual mode, strength 0x32
    assert TOPOTEK.decode(parse_frame("#tpPD3wDFG232AD")).fields == {"mode": "manual", "strength": 0x32}
    assert TOPOTEK.encode("DFG", mode="manual", strength=0x32, src="P").to_bytes() == b"#tpPD3wDFG232AD"


def test_worked_example_time() -> None:
    # SkyDroid §4.6: #tpUDFwTIM142832.0003121838 = 2018-12-03 14:28:32
    frame = parse_frame("#tpUDFwTIM142832.0003121838")
    assert SKYDROID.decode(frame).fields == {"time": datetime(2018, 12, 3, 14, 28, 32)}
    assert SKYDROID.encode("TIM", time=datetime(2018, 12, 3, 14, 28, 32)).to_bytes() == frame.to_bytes()


def test_worked_example_digital_zoom_topotek() -> None:
    # TOPOTEK §五.14.1: X0 = 0 visible / 1 thermal, 0A = zoom in 0.5x per step
    assert TOPOTEK.decode(parse_frame("#tpUD3wDZM00AD6")).fields == {"lens": "visible", "zoom": "step_in"}
    assert TOPOTEK.decode(parse_frame("#tpUD3wDZM10AD7")).fields == {"lens": "thermal", "zoom": "step_in"}


def test_worked_example_error_frame() -> None:
    # SkyDroid §2.3.2: #TPdd2wERE!!RR, e.g. #TPMU2wERE!!30 (addresses swapped: from the lens M)
    frame = parse_frame("#TPMU2wERE!!30")
    msg = SKYDROID.decode(frame)
    assert msg.is_error and msg.fields == {"error": "!!"}
    assert direction_of(frame) == RESPONSE


# -- the frames the documents get wrong (seeds README), exactly ------------------------------------


@pytest.mark.parametrize(
    ("text", "expected", "tp_spelling"),
    [(GAY_TP, "48", "#tpUG6wGAYEF073288"), (GOT_TP, "95", "#tpUG8wGOT02800168D5")],
    ids=["§3.3.1-GAY", "§3.3.5-GOT"],
)
def test_skydroid_gimbal_examples_carry_the_lowercase_checksum(text: str, expected: str, tp_spelling: str) -> None:
    """SkyDroid G-class examples use #TP (§2.2.2) but carry the checksum of the #tp spelling."""
    raw = text.encode()
    assert crc_of(raw[:-2]) == expected
    assert crc_of(tp_spelling[:-2]) == text[-2:]  # 88 / D5 = checksum of the #tp spelling
    d = dissect(raw)
    assert not d.ok and d.frame is None
    assert d.error is not None and d.error.startswith("bad checksum")
    assert (d.checksum, d.expected_checksum) == (text[-2:], expected)
    p = parts(text)
    assert (d.header, d.src, d.dst, d.rw) == ("#TP", "U", "G", "w")
    assert (d.length, d.ident, d.data) == (p.length, p.ident, p.data)
    with pytest.raises(ChecksumError) as err:
        parse_frame(raw)
    assert (err.value.expected, err.value.found) == (expected, text[-2:])
    # the #tp spelling is a good frame (TOPOTEK §四.3.1 prints it for GAY)
    assert dissect(tp_spelling.encode()).ok
    # the streaming parser drops exactly this frame and delivers the next one
    good = b"#TPUG2wPTZ006A"
    for step in (None, 1):
        diag, frame = run_parser(raw + good, step)
        assert isinstance(diag, Diagnostic) and (diag.kind, diag.raw) == ("bad_checksum", raw)
        assert repr(expected) in diag.detail
        assert frame == parse_frame(good)
    # corrected, it means what the document says
    fixed = parse_frame(text[:-2] + expected)
    assert fixed.header == "#TP"
    assert SKYDROID.encode(fixed.ident, **SKYDROID.decode(fixed).fields).to_bytes() == fixed.to_bytes()


def test_skydroid_gay_example_means_minus_43_45() -> None:
    fixed = parse_frame("#TPUG6wGAYEF073248")
    assert SKYDROID.decode(fixed).fields == {"yaw_deg": pytest.approx(-43.45), "speed_deg_s": pytest.approx(5.0)}
    assert SKYDROID.encode("GAY", yaw_deg=-43.45, speed_deg_s=5.0).to_bytes() == b"#TPUG6wGAYEF073248"


def test_skydroid_got_example_means_640_360() -> None:
    fixed = parse_frame("#TPUG8wGOT0280016895")
    assert SKYDROID.decode(fixed).fields == {"x_px": 640, "y_px": 360}
    assert SKYDROID.encode("GOT", x_px=640, y_px=360).to_bytes() == b"#TPUG8wGOT0280016895"


def test_skydroid_fai_example_has_13_data_characters() -> None:
    """§3.3.6.2 `#TPUGCwFAIEC7800000000064`: length C (12) but 13 data characters; its checksum 64
    is that of the 12-character data EC78 0000 0000 (one '0' too many in the document)."""
    raw = FAI_13.encode()
    assert int(FAI_13[5], 16) == 12
    assert len(raw) - 12 == 13
    assert crc_of("#TPUGCwFAIEC7800000000") == "64"
    assert crc_of(raw[:-2]) == "94"
    for recover in (False, True):
        d = dissect(raw, recover_length=recover)
        assert not d.ok and d.frame is None
        assert d.length == 12
        assert d.data == b"EC78000000000" and len(d.data) == 13
        # The library checks the checksum first: over the bytes as printed it is wrong as well.
        assert d.error is not None and d.error.startswith("bad checksum")
        assert (d.checksum, d.expected_checksum) == ("64", "94")
    with pytest.raises(ChecksumError) as err:
        parse_frame(raw)
    assert (err.value.expected, err.value.found) == ("94", "64")
    # The streaming parser takes the declared 12 characters, finds checksum "06" (expected 64) and
    # no other length whose checksum fits: the frame is dropped, never accepted as a 12-char frame.
    good = b"#TPUG2wFAE0139"
    for step in (None, 1, 5):
        out = run_parser(raw + good, step)
        assert frames_of(out) == [parse_frame(good)]
        diags = diagnostics_of(out)
        assert [d.kind for d in diags] == ["bad_checksum", "garbage"]
        assert diags[0].raw == raw[:24] == b"#TPUGCwFAIEC780000000006"
        assert "'06'" in diags[0].detail and "'64'" in diags[0].detail
        assert diags[1].raw == b"4"
    p = FrameParser()
    p.feed(raw)
    p.flush()
    assert (p.stats.frames, p.stats.bad_checksums, p.stats.length_recoveries) == (0, 1, 0)
    # What the document meant: yaw -50 deg, pitch 0, roll 0
    intended = SKYDROID.encode("FAI", yaw_deg=-50, pitch_deg=0, roll_deg=0)
    assert intended.to_bytes() == b"#TPUGCwFAIEC780000000064"
    assert SKYDROID.decode(intended).fields == {"yaw_deg": -50, "pitch_deg": 0, "roll_deg": 0}


def test_skydroid_vom_set_example_checksum() -> None:
    """§4.10.1 `#tpUDBwVOM111E1E04001AE`: the checksum is 8E."""
    raw = VOM_SET.encode()
    d = dissect(raw)
    assert not d.ok and d.error is not None and d.error.startswith("bad checksum")
    assert (d.checksum, d.expected_checksum) == ("AE", "8E")
    assert (d.header, d.length, len(d.data or b""), d.ident) == ("#tp", 11, 11, "VOM")
    with pytest.raises(ChecksumError) as err:
        parse_frame(raw)
    assert (err.value.expected, err.value.found) == ("8E", "AE")
    (diag,) = run_parser(raw)
    assert isinstance(diag, Diagnostic) and (diag.kind, diag.raw) == ("bad_checksum", raw)
    assert "'8E'" in diag.detail
    # The values of the example (flip both, 30 fps, gop 30, 1024 kbps, output on) encode to ...8E,
    # the same data as the §4.10.1 read reply example #tpDUBrVOM111E1E0400189.
    values = {"h_flip": "on", "v_flip": "on", "fps": 30, "gop": 30, "bitrate_kbps": 1024, "output": "on"}
    assert SKYDROID.encode("VOM", **values).to_bytes() == b"#tpUDBwVOM111E1E040018E"
    assert SKYDROID.decode(parse_frame("#tpUDBwVOM111E1E040018E")).fields == values


def test_skydroid_slr_reply_example() -> None:
    """§4.22.1 reply `#TPUD4rSLR0005BC`: checksum right, but `#TP` (fixed length 2, §2.2.1) with
    length 4, and the query's addresses (U -> D) instead of D -> U."""
    frame = parse_frame("#TPUD4rSLR0005BC")
    assert frame.header == "#TP" and frame.length == 4 and frame.data == b"0005"
    query = parse_frame("#TPUD2rSLR0055")
    assert (frame.src, frame.dst) == (query.src, query.dst) == ("U", "D")
    assert direction_of(frame) == REQUEST
    msg = SKYDROID.decode(frame.swapped())
    assert msg.fields == {"distance_m": pytest.approx(0.5)}  # 0005 = 5 dm
    answer = SKYDROID.response(query, distance_m=0.5)
    assert (answer.src, answer.dst, answer.data) == ("D", "U", b"0005")
    assert answer.header == "#tp"  # the encoder uses #tp for 4 data characters


def test_skydroid_uid_reply_example() -> None:
    """§4.13.2 gives `#tpUD8wUID00000001B2` as the reply to `#TPUD2rUID0046`: it is the §4.13.1 set
    command verbatim (`w`, U -> D), where the template says `#tpDU8rUID...`."""
    (set_cmd,) = [e for e in EXAMPLES if e.section == "§4.13.1"]
    (reply_eg,) = [e for e in EXAMPLES if e.section == "§4.13.2 reply"]
    assert reply_eg.text == set_cmd.text
    frame = parse_frame(reply_eg.text)
    assert (frame.rw, frame.src, frame.dst) == ("w", "U", "D")
    assert direction_of(frame) == REQUEST
    answer = SKYDROID.response(parse_frame("#TPUD2rUID0046"), uid=1)
    assert answer.to_bytes() == with_crc("#tpDU8rUID00000001").encode()
    assert SKYDROID.decode(answer).fields == {"uid": 1}


def test_skydroid_ext_reply_template_keeps_query_addresses() -> None:
    """§4.12.2 `Receive: #tpUD4rEXTx0x1x2x3RR` (template) keeps the query's U -> D."""
    template = "#tpUD4rEXTx0x1x2x3RR"
    assert template[3:5] == parts("#TPUD2rEXT0055").src + parts("#TPUD2rEXT0055").dst
    rendered = parse_frame(with_crc("#tpUD4rEXT0011"))
    assert direction_of(rendered) == REQUEST
    as_is = SKYDROID.decode(rendered)
    assert as_is.fields is None or as_is.fields["osd"] == "on"
    assert SKYDROID.decode(rendered.swapped()).fields == {
        "reserved": "zero",
        "dish_calibration": "off",
        "osd": "on",
        "led": "on",
    }


def test_topotek_tmp_12_2_malformed_header() -> None:
    """§五.12.2 `#PDP16TMP X..RR`: the document itself says the frame does not follow the format.
    A concrete rendering fails on the header; the frame TOPOTEK presumably means (`#tP`, raw length
    0x16 = 22) decodes with the §12.2 form."""
    data = "0A0" + "80" + "016D" + "000" + "00" + "00C8" + "0190"  # hot (160,128) 36.5, cold (0,0) 20.0, centre 40.0
    assert len(data) == 0x16
    raw = with_crc("#PDP16TMP" + data).encode()
    d = dissect(raw)
    assert not d.ok and d.frame is None
    assert d.error is not None and "'#PD'" in d.error and "header" in d.error
    with pytest.raises(FrameError):
        parse_frame(raw)
    out = run_parser(raw)
    assert frames_of(out) == []
    assert [x.kind for x in diagnostics_of(out)] == ["bad_header", "garbage"]
    meant = make_frame("TMP", data, src="D", dst="P", rw="w", header="#tP")
    assert meant.to_bytes()[:7] == b"#tPDP\x16w"
    assert TOPOTEK.decode(meant).fields == {
        "hot_x_px": 160,
        "hot_y_px": 128,
        "hot_temp_c": pytest.approx(36.5),
        "cold_x_px": 0,
        "cold_y_px": 0,
        "cold_temp_c": pytest.approx(20.0),
        "center_temp_c": pytest.approx(40.0),
    }
    assert run_parser(meant.to_bytes()) == [meant]


def test_appendix_checksum_example() -> None:
    # both appendices: the sum of "#TPUD2wAWB01" is 0x44 -> "#TPUD2wAWB0144"
    assert sum(b"#TPUD2wAWB01") % 256 == 0x44
    assert with_crc("#TPUD2wAWB01") == "#TPUD2wAWB0144"


# -- frames real devices send (seeds README) -----------------------------------------------------


def test_c12_version_reply_with_wrong_length_character() -> None:
    """A real C12 answers `#tpDU3rVER0105025A`: length 3, six data characters, checksum over six."""
    raw = b"#tpDU3rVER0105025A"
    assert crc_of(raw[:-2]) == "5A"
    d = dissect(raw)
    assert d.ok and d.error is None
    assert d.anomaly is not None and "3" in d.anomaly and "6" in d.anomaly
    assert d.frame == Frame("#tp", "D", "U", "r", "VER", b"010502", 3)
    assert d.frame.length == 3 and d.frame.to_bytes() == raw
    strict = dissect(raw, recover_length=False)
    assert not strict.ok and strict.error is not None and "length" in strict.error
    assert (strict.length, strict.data) == (3, b"010502")
    for step in (None, 1, 4):
        out = run_parser(raw + b"#TPUD2rVER0051", step)
        assert len(out) == 3
        diag, frame, nxt = out
        assert isinstance(diag, Diagnostic) and diag.kind == "length_mismatch" and diag.raw == raw
        assert frame == Frame("#tp", "D", "U", "r", "VER", b"010502", 3)
        assert frame.declared_length == 3 and frame.data == b"010502"
        assert nxt == parse_frame("#TPUD2rVER0051")
    assert SKYDROID.decode(d.frame).fields == {"version": "010502"}


def test_real_gac_reply_decodes() -> None:
    """`#tpGPCrGACFF36ED5A0048DE`: lower-case header, swapped addresses (G -> P)."""
    frame = parse_frame("#tpGPCrGACFF36ED5A0048DE")
    assert (frame.header, frame.src, frame.dst, frame.rw, frame.ident) == ("#tp", "G", "P", "r", "GAC")
    msg = TOPOTEK.decode(frame)
    assert msg.error is None
    assert msg.fields == {
        "yaw_deg": pytest.approx(-2.02),
        "pitch_deg": pytest.approx(-47.74),
        "roll_deg": pytest.approx(0.72),
    }
    query = parse_frame(with_crc("#TPPG2rGAC00"))
    assert TOPOTEK.response(query, header="#tp", **msg.fields).to_bytes() == frame.to_bytes()


# -- the documents as byte streams ------------------------------------------------------------------


@pytest.mark.parametrize("doc", ["skydroid", "topotek"])
@pytest.mark.parametrize("step", [None, 1, 3, 64])
def test_all_examples_as_one_stream(doc: str, step: int | None) -> None:
    texts = [e.text for e in EXAMPLES if e.doc == doc]
    stream = b"\r\n".join(t.encode() for t in texts)
    out = run_parser(stream, step)
    assert out == [parse_frame(t) for t in texts]


@pytest.mark.parametrize("doc", ["skydroid", "topotek"])
def test_table_holds_every_literal_frame_of_the_document(doc: str) -> None:
    """Every `#xx...` token of the document whose checksum and length check out is in the table, in
    document order (and nothing else is), and the wrong frames occur verbatim."""
    text = (SEEDS / DOCUMENTS[doc]).read_text("utf-8")
    found = []
    for token in re.findall(r"#[A-Za-z]{2}[^\s，；,;\"}]*", text):
        if len(token) >= 12 and token[-2:] == crc_of(token[:-2]) and int(token[5], 16) == len(token) - 12:
            found.append(token)
    assert found == [e.text for e in EXAMPLES if e.doc == doc]
    for wrong in WRONG[doc]:
        assert wrong in text


@pytest.mark.parametrize("doc", ["skydroid", "topotek"])
@pytest.mark.parametrize("step", [None, 1, 7])
def test_parser_finds_exactly_the_examples_in_the_document_text(doc: str, step: int | None) -> None:
    """The whole document (UTF-8 text, templates, C code) through the streaming parser yields exactly
    the table's frames in order; the wrong frames come out as bad_checksum diagnostics."""
    raw = (SEEDS / DOCUMENTS[doc]).read_bytes()
    expected = [parse_frame(e.text) for e in EXAMPLES if e.doc == doc]
    out = run_parser(raw, step)
    assert frames_of(out) == expected
    bad = [d.raw for d in diagnostics_of(out) if d.kind == "bad_checksum"]
    for wrong in WRONG[doc]:
        assert any(wrong.encode().startswith(b) or b.startswith(wrong.encode()) for b in bad), wrong
    assert not [d for d in diagnostics_of(out) if d.kind == "length_mismatch"]
