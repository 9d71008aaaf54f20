"""The generator's own rules: unknown codec kinds fail loudly, Lua literals, Info names."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import pytest

from topgimbal.protocol.fields import Codec, HexInt
from topgimbal.wire.dissector import DissectorError, catalog_tables, codec_entry, short_name, to_lua

pytestmark = pytest.mark.virtual


@dataclass(frozen=True)
class Morse(Codec):
    """A codec kind the dissector has never heard of."""

    width: int = 2
    kind: str = "morse"

    def decode(self, raw: bytes) -> Any:
        return raw


def test_unknown_codec_kind_fails_loudly():
    with pytest.raises(DissectorError, match=r"GAC field yaw: codec Morse \(kind 'morse'\) is unknown"):
        codec_entry(Morse(), "skydroid GAC field yaw")


def test_known_class_with_another_kind_fails_too():
    @dataclass(frozen=True)
    class OddHex(HexInt):
        kind: str = "bitfield"

    with pytest.raises(DissectorError, match="OddHex"):
        codec_entry(OddHex(2), "x")


def test_lua_literals():
    assert to_lua({"a": 1, "end": "x", 5: [1.5, True], b"\x00\xff": None}) == '{a=1, ["end"]="x", [5]={1.5, true}}'
    assert to_lua('q"\\\n°') == '"q\\"\\\\\\010\\194\\176"'  # text as UTF-8 bytes
    assert to_lua(b"\xff#") == '"\\255#"'  # wire bytes byte for byte
    with pytest.raises(DissectorError):
        to_lua(float("nan"))


@pytest.mark.parametrize(
    ("name", "unit", "short"),
    [
        ("yaw_deg", "deg", "yaw"),
        ("speed_deg_s", "deg/s", "speed"),
        ("avg_temp_c", "degC", "avg_temp_c"),
        ("x_px", "", "x_px"),
        ("deg", "deg", "deg"),
    ],
)
def test_info_names_drop_the_unit(name, unit, short):
    assert short_name(name, unit) == short


def test_tables_cover_both_dialects_and_the_documented_ports():
    t = catalog_tables()
    assert t["dialect_order"] == ["skydroid", "topotek"]
    assert t["ports"]["udp"] == {5000: "skydroid", 9002: "skydroid", 9003: "topotek", 9004: "topotek"}
    assert t["ports"]["tcp"] == {5000: "skydroid"}
    assert t["field_types"]["yaw_deg"] == "double" and t["field_types"]["action"] == "string"
    assert t["field_types"]["lens"] == "string"  # a number in one command, an enum in another
