"""Field codecs at their edges."""

from __future__ import annotations

from datetime import datetime

import pytest

from topgimbal.errors import FieldValueError
from topgimbal.protocol.fields import (
    BinInt,
    Bitrate,
    DecFloat,
    DecInt,
    GeoDeg,
    GeoDM,
    HexInt,
    IPv4Text,
    OneOf,
    Text,
    Timestamp,
    enum,
)

pytestmark = pytest.mark.virtual


def test_hexint_signed_scaled() -> None:
    c = HexInt(4, signed=True, scale=0.01, unit="deg", min=-90, max=90)
    assert c.encode(-50) == b"EC78" and c.decode(b"EC78") == -50.0
    assert c.encode(-43.45) == b"EF07" and c.decode(b"ef07") == -43.45
    with pytest.raises(FieldValueError, match=r"yaw_deg=90.01 .*-90..90 deg in steps of 0.01"):
        c.encode(90.01, "yaw_deg")
    for bad in (b"EC7", b"0x12", b"+123", b" 123", b"EC7G"):
        with pytest.raises(ValueError):
            c.decode(bad)


def test_hexint_none_token() -> None:
    c = HexInt(5, unit="MB", none_tokens=(b"NNNNN",))
    assert c.decode(b"NNNNN") is None and c.encode(None) == b"NNNNN"
    assert c.decode(b"0FFFF") == 65535


def test_decimal_codecs() -> None:
    mul = DecInt(4, scale=0.1, unit="x")
    assert mul.encode(12.3) == b"0123" and mul.decode(b"0123") == 12.3
    with pytest.raises(ValueError):
        mul.decode(b"01A3")
    alt = DecFloat(None, 1, "m", -9999.9, 9999.9, pad=8)
    assert alt.encode(-12.3) == b"-00012.3" and alt.decode(b"-00012.3") == -12.3 and alt.decode(b"5.5") == 5.5
    lrf = DecFloat(None, 1, "m", 0, 99999.9, none_tokens=(b"ERR",), pad=7)
    assert lrf.encode(123.4) == b"00123.4" and lrf.decode(b"ERR") is None
    with pytest.raises(ValueError):
        lrf.decode(b"nan")


def test_enum_lookup_by_name_raw_and_int() -> None:
    e = enum(2, {"00": "stop", "0A": ("toggle", "Toggle")}, toggles="0A")
    assert e.encode("toggle") == e.encode("0A") == e.encode(10) == b"0A"
    assert e.decode(b"0a") == "toggle"  # lower-case hex spelling from some firmware
    assert not e.is_idempotent(b"0A") and e.is_idempotent(b"00")
    with pytest.raises(FieldValueError, match="one of stop \\(00\\), toggle \\(0A\\)"):
        e.encode("go")


def test_one_of_tokens_or_number() -> None:
    c = OneOf(enum(2, {"0A": "step_in", "0E": "stop"}, toggles="0A"), DecInt(2, scale=0.1, max=8.0))
    assert c.encode("step_in") == b"0A" and c.encode(2.5) == b"25" and c.encode("2.5") == b"25"
    assert c.decode(b"0E") == "stop" and c.decode(b"80") == 8.0
    with pytest.raises(FieldValueError, match=r"0\.\.8"):
        c.encode(9)


def test_text_and_ip() -> None:
    assert Text(1, 15).encode("V1.0.0") == b"V1.0.0"
    with pytest.raises(FieldValueError):
        Text(1, 15).encode("é")
    with pytest.raises(FieldValueError):
        Text(1, 3).encode("abcd")
    ip = IPv4Text()
    assert ip.encode("127.0.0.5") == b"127.0.0.5" and ip.decode(b"127.0.0.5") == "127.0.0.5"
    with pytest.raises(FieldValueError, match="dotted IPv4"):
        ip.encode("1.2.3")


def test_coordinates() -> None:
    lat, lon = GeoDM("lat"), GeoDM("lon")
    assert lat.encode(22.5) == b"N2230.0000" and lat.decode(b"N2230.0000") == 22.5
    assert lon.encode(-113.25) == b"W11315.0000" and lon.decode(b"W11315.0000") == -113.25
    assert lat.decode(b"N 2230.0000") == 22.5  # a space after the hemisphere is tolerated
    with pytest.raises(FieldValueError):
        lat.encode(91)
    with pytest.raises(ValueError):
        lat.decode(b"X2230.0000")
    tgt = GeoDeg("lon")
    assert tgt.encode(113.123456) == b"E113.123456" and tgt.decode(b"W113.123456") == -113.123456
    with pytest.raises(ValueError):
        tgt.decode(b"E11307.4074")  # a ddmm.mmmm spelling is not the target form


def test_timestamps() -> None:
    sky = Timestamp("%H%M%S.%f2%d%m%y")
    t = datetime(2018, 12, 3, 14, 28, 32)
    assert sky.encode(t) == b"142832.00031218" and sky.decode(b"142832.00031218") == t
    assert sky.decode(b"142832.50031218").microsecond == 500000
    assert Timestamp("%Y%m%d%H%M%S").encode("2024-01-02T03:04:05") == b"20240102030405"
    with pytest.raises(FieldValueError):
        sky.encode("yesterday")
    with pytest.raises(FieldValueError, match=r"2000\.\.2099"):
        Timestamp("%H%M%S%d%m%y").encode(datetime(1999, 1, 1))


def test_binary_and_bitrate() -> None:
    c = BinInt(4, True, "little", 1e-7, "deg", -180, 180)
    assert c.decode(c.encode(-113.5)) == -113.5 and len(c.encode(1)) == 4
    assert BinInt(2, True, "big").encode(-2) == b"\xff\xfe"
    b = Bitrate()
    assert b.encode(2000) == b"020000" and b.encode(1234) == b"K01234"
    assert b.decode(b"K01234") == 1234 and b.decode(b"02") == 2000 and b.decode(b"030000") == 3000
    with pytest.raises(FieldValueError):
        b.encode(20)
