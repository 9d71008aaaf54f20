"""Issue 9, codec side: each hostile input that once escaped as the wrong exception, an invalid frame
or a second frame, now refused with a FieldValueError naming the field and what is allowed."""

from __future__ import annotations

from datetime import datetime

import pytest

from topgimbal.errors import (
    DecodeError,
    DeviceError,
    FieldValueError,
    FrameError,
    RequestTimeoutError,
    TopGimbalError,
    UnknownCommandError,
)
from topgimbal.protocol import Frame, FrameParser, Message, decode, decode_any, get_dialect, make_frame

pytestmark = pytest.mark.virtual

SKY, TOP = get_dialect("skydroid"), get_dialect("topotek")


@pytest.mark.parametrize(
    ("dialect", "ident", "field", "value"),
    [
        (SKY, "GAY", "yaw_deg", 10**400),  # was OverflowError
        (SKY, "GAY", "yaw_deg", -(2**64)),
        (TOP, "GPS", "lat_deg", 10**30),  # a packed struct: was OverflowError from int.to_bytes
        (TOP, "MUL", "magnification_x", 10**20),
        (TOP, "DZM", "zoom", 1.7e308),  # a finite float whose raw form overflows: was OverflowError
        (TOP, "UAV", "yaw_deg", -1.7e308),
        (TOP, "ALT", "alt_m", 10**300),
        (TOP, "LAT", "lat_deg", 10**400),
        (TOP, "BIT", "bitrate_kbps", 10**400),
        (SKY, "GAY", "yaw_deg", True),
        (SKY, "PTZ", "action", True),  # a bool is not an enum value either
        (SKY, "GAY", "yaw_deg", float("nan")),
        (SKY, "GAY", "yaw_deg", float("inf")),
        (SKY, "GAY", "yaw_deg", "1e400"),
        (SKY, "GAY", "yaw_deg", [1]),
        (SKY, "GAY", "yaw_deg", b"12"),
        (TOP, "TIM", "time", datetime(5, 1, 1)),  # was an invalid 11-character TIM frame
        (SKY, "TIM", "time", datetime(1999, 12, 31)),
        (TOP, "UTC", "time", 20240101),
        (SKY, "IPV", "address", 3232235777),
        (SKY, "IPV", "address", "192.168.1.1#"),
    ],
)
def test_out_of_range_and_wrong_typed_values_are_refused(dialect, ident, field, value) -> None:  # type: ignore[no-untyped-def]
    with pytest.raises(FieldValueError) as exc:
        dialect.encode(ident, **{field: value, **_others(dialect, ident, field)})
    assert exc.value.field == field and exc.value.allowed
    assert isinstance(exc.value, ValueError) and exc.value.kind == "value"
    assert len(str(exc.value)) < 400  # a 10**400 never floods the message


def _others(dialect, ident, field):  # type: ignore[no-untyped-def]
    """Valid values for the other required fields of the write form."""
    form = dialect.command(ident).request_form("w", [field])
    sample = {"lon_deg": 1.0, "lat_deg": 1.0, "alt_m": 1.0, "heading_deg": 0.0}
    return {f.name: sample.get(f.name, 0) for f in form.fields if f.name != field and f.default is None}


@pytest.mark.parametrize("text", ["V1#TPUG2wPTZ006A", "V1\r\n", "a\nb", "x\x00", "é", "#", "\x7f"])
def test_text_cannot_inject_a_frame(text: str) -> None:
    with pytest.raises(FieldValueError, match=r"printable ASCII text .* without '#'"):
        TOP.response(TOP.encode("PA2", read=True), model=text)


def test_raw_data_refuses_frame_delimiters_unless_binary() -> None:
    with pytest.raises(FieldValueError, match="no 23"):
        SKY.encode("MNU", data="23545055")  # "#TPU"
    with pytest.raises(FieldValueError):
        SKY.encode("MNU", data="0d0a")
    frame = TOP.encode("LOC", x_px=35, y_px=0, width_px=0, height_px=0, reserved="2323")  # binary struct: fine
    assert FrameParser().feed(frame.to_bytes()) == [frame]


def test_header_and_control_cannot_disagree() -> None:
    with pytest.raises(FieldValueError, match="#Tp frame has no r/w"):
        TOP.encode("GAC", read=True, header="#Tp")
    with pytest.raises(FieldValueError, match="one of #TP, #tp in the skydroid"):
        SKY.encode("GAC", read=True, header="#tP")
    with pytest.raises(FieldValueError, match="#Tp"):
        TOP.response(TOP.encode("GAC", read=True), header="#Tp", yaw_deg=0, pitch_deg=0, roll_deg=0)
    assert TOP.encode("GAY", yaw_deg=1, header="#Tp").rw == ""  # a write may use #Tp


def test_unknown_control_and_identifier_are_unknown_forms_not_key_errors() -> None:
    odd = Frame("#TP", "U", "G", "x", "GAA", b"01")
    for d in (SKY, TOP):
        msg = d.decode(odd)
        assert msg.fields is None and "unknown form" in (msg.error or "") and msg.dialect == d.name
    msg = SKY.decode(Frame("#TP", "U", "G", "w", "QQQ", b"00"))
    assert msg.spec is None and "not in the skydroid catalog" in (msg.error or "")


def test_decode_falls_back_across_dialects_and_says_which() -> None:
    bit = make_frame("BIT", "00", src="U", dst="D", rw="r")  # a SkyDroid-looking frame only TOPOTEK knows
    msg = decode("skydroid", bit)
    assert msg.fields == {} and msg.dialect == "topotek" and msg.spec is not None and msg.spec.ident == "BIT"
    assert decode("skydroid", bit, fallback=False).fields is None
    assert decode_any(make_frame("PTZ", "06", dst="G"), prefer="topotek").fields == {"action": "lock"}
    nobody = decode_any(make_frame("QQQ", "00"))
    assert nobody.fields is None and "also tried" in (nobody.error or "")


def test_message_keeps_positional_construction_and_gains_dialect() -> None:
    frame = make_frame("PTZ", "00", dst="G")
    legacy = Message(frame, None, None, None, "sent without waiting for a reply")
    assert legacy.error == "sent without waiting for a reply" and legacy.dialect is None
    assert SKY.decode(frame).to_dict()["dialect"] == "skydroid"


def test_error_kinds_and_request_frames() -> None:
    req = SKY.encode("VER", read=True)
    cases = [
        (FrameError("x"), "frame"),
        (UnknownCommandError("x"), "unknown_command"),
        (FieldValueError("f", 1, "0..0"), "value"),
        (DeviceError("x", request=req), "device"),
        (DecodeError("cannot read", answer=req, request=req), "decode"),
        (RequestTimeoutError("x", request=req), "timeout"),
    ]
    for err, kind in cases:
        assert isinstance(err, TopGimbalError) and err.kind == kind
    assert cases[3][0].request is req and cases[4][0].answer is req and FrameError("x").request is None
    assert isinstance(cases[4][0], DeviceError)  # code catching DeviceError keeps catching it
    assert isinstance(cases[5][0], TimeoutError) and isinstance(cases[1][0], KeyError)
