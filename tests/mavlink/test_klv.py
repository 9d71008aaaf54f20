"""MISB ST 0601 packets read back by klvdata (an independent parser): every tag's value within
its quantisation, the checksum right, unknown and out-of-range values left out."""

from __future__ import annotations

import klvdata
import pytest

from topgimbal.outputs.klv import UAS_LS_KEY, checksum, packet

pytestmark = pytest.mark.virtual

VALUES = {
    5: 123.45, 6: -3.5, 7: 12.25, 13: 47.0012345, 14: 8.0054321, 15: 640.5, 16: 62.0, 17: 36.4,
    18: 20.0, 19: -28.0, 21: 412.3, 23: 46.9987654, 24: 8.0076543, 25: 331.2,
}  # fmt: skip


def _parsed(data: bytes) -> dict[str, object]:
    (ls,) = list(klvdata.StreamParser(data))
    out = {}
    for key, item in ls.items.items():
        out[str(item.LDSName if hasattr(item, "LDSName") else key)] = item.value.value
    return out


def test_klvdata_reads_back_every_tag() -> None:
    data = packet(1_764_300_000_123_456, VALUES)
    assert data.startswith(UAS_LS_KEY)
    v = _parsed(data)
    assert v["Platform Heading Angle"] == pytest.approx(123.45, abs=0.01)
    assert v["Platform Pitch Angle"] == pytest.approx(-3.5, abs=0.001)
    assert v["Platform Roll Angle"] == pytest.approx(12.25, abs=0.002)
    assert v["Sensor Latitude"] == pytest.approx(47.0012345, abs=1e-7)
    assert v["Sensor Longitude"] == pytest.approx(8.0054321, abs=1e-7)
    assert v["Sensor True Altitude"] == pytest.approx(640.5, abs=0.3)
    assert v["Sensor Horizontal Field of View"] == pytest.approx(62.0, abs=0.003)
    assert v["Sensor Vertical Field of View"] == pytest.approx(36.4, abs=0.003)
    assert v["Sensor Relative Azimuth Angle"] == pytest.approx(20.0, abs=1e-6)
    assert v["Sensor Relative Elevation Angle"] == pytest.approx(-28.0, abs=1e-6)
    assert v["Slant Range"] == pytest.approx(412.3, abs=0.01)
    assert v["Frame Center Latitude"] == pytest.approx(46.9987654, abs=1e-7)
    assert v["Frame Center Longitude"] == pytest.approx(8.0076543, abs=1e-7)
    assert v["Frame Center Elevation"] == pytest.approx(331.2, abs=0.3)
    assert int(v["UAS Datalink LS Version Number"]) == 17
    # the checksum covers everything before its two value bytes
    assert int.from_bytes(data[-2:], "big") == checksum(data[:-2])


def test_unknown_and_out_of_range_values_are_left_out() -> None:
    data = packet(1, {6: 45.0, 13: float("nan"), 14: None, 16: 30.0})  # pitch 45: beyond +-20
    v = _parsed(data)
    assert "Platform Pitch Angle" not in v and "Sensor Latitude" not in v and "Sensor Longitude" not in v
    assert v["Sensor Horizontal Field of View"] == pytest.approx(30.0, abs=0.003)
    with pytest.raises(ValueError):
        packet(1, {99: 1.0})
