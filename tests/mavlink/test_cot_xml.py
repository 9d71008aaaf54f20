"""Every CoT event is well-formed XML of at most MAX_EVENT_BYTES, whatever the names and URLs (read
back by lxml, i.e. libxml2, not the expat that wrote it, and by takproto); a vehicle at 0, 0 or
at no finite position is not sent; `hae` is the MSL height plus the EGM96 undulation (checked
against pyproj's own CRS route, not the grid pipeline the code uses), unknown without a grid."""

from __future__ import annotations

import logging
import math

import pytest
import takproto
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from lxml import etree

from topgimbal.geo import Fix as GeoFix
from topgimbal.geo import geoid
from topgimbal.mavlink import BridgeConfig
from topgimbal.outputs.cot import MAX_EVENT_BYTES, UNKNOWN, CotConfigError, Sighting, check_text, events

pytestmark = pytest.mark.virtual

LAT, LON = -35.36, 149.16


def _fix(lat: float, lon: float, alt: float = 600.0, source: str = "terrain") -> GeoFix:
    return GeoFix(lat, lon, alt, 250.0, source, 4.0, 30.0, -30.0)  # type: ignore[arg-type]


def _sighting(lat: float = LAT, lon: float = LON, alt: float = 700.0, url: str | None = None) -> Sighting:
    corners = [_fix(lat + dy, lon + dx) for dy, dx in ((1e-3, -1e-3), (1e-3, 1e-3), (-1e-3, 1e-3), (-1e-3, -1e-3))]
    return Sighting(lat, lon, alt, 30.0, -30.0, 0.0, 60.0, 34.0, _fix(lat + 2e-3, lon), corners, url)


def _parse_all(data: list[bytes]) -> list[etree._Element]:
    out = []
    for d in data:
        assert len(d) <= MAX_EVENT_BYTES
        out.append(etree.fromstring(d))  # raises on anything not well-formed
        assert takproto.parse_proto(bytearray(d)) is not None
    return out


# names and URLs as anything may hand them over: controls, surrogates, other planes, very long
ANY_TEXT = st.text(st.characters(codec=None, blacklist_categories=()), max_size=12000)


@settings(max_examples=100, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(uid=ANY_TEXT, callsign=ANY_TEXT, url=st.one_of(st.none(), ANY_TEXT, st.text(max_size=20).map(
    lambda s: f"rtsp://127.0.0.1:8554/{s}")))  # fmt: skip
def test_every_event_is_well_formed_xml_within_the_limit(uid: str, callsign: str, url: str | None) -> None:
    data = events(_sighting(url=url), uid=uid, callsign=callsign, now=1.7e9)
    parsed = _parse_all(data)
    # the vehicle goes out whenever its bare event fits; here every uid and callsign this long still fits
    if len(uid.encode("utf-8", "replace")) + 2 * len(callsign.encode("utf-8", "replace")) < 2000:
        assert parsed and parsed[0].get("type") == "a-f-A-M-F-Q"


def test_a_long_video_url_drops_the_video_detail_not_the_event(caplog: pytest.LogCaptureFixture) -> None:
    url = "rtsp://127.0.0.1:8554/" + "a" * 9000
    with caplog.at_level(logging.WARNING, "topgimbal.mavlink"):
        data = events(_sighting(url=url), uid="topgimbal-C12-1", callsign="C12 1", now=1.7e9)
    vehicle = _parse_all(data)[0]
    assert vehicle.get("type") == "a-f-A-M-F-Q"
    assert vehicle.find("detail/__video") is None and vehicle.find("detail/sensor") is not None
    assert "sent without its __video" in caplog.text
    short = events(_sighting(url="rtsp://127.0.0.1:8554/main"), uid="u", callsign="c", now=1.7e9)
    assert etree.fromstring(short[0]).find("detail/__video").get("url") == "rtsp://127.0.0.1:8554/main"


def test_an_event_that_cannot_fit_is_not_sent(caplog: pytest.LogCaptureFixture) -> None:
    with caplog.at_level(logging.WARNING, "topgimbal.mavlink"):
        data = events(_sighting(), uid="u" * 9000, callsign="c", now=1.7e9)
    assert data == []  # every event carries the uid: none fits, none is cut
    assert "not sent" in caplog.text


def test_control_characters_are_refused_before_anything_starts() -> None:
    for bad in ("rtsp://127.0.0.1/a\x00b", "rtsp://127.0.0.1/\x1b[31m", "rtsp://127.0.0.1/\x7f", "rtsp://h/\n"):
        with pytest.raises(CotConfigError, match="control character"):
            check_text("video URL", bad)
        config = BridgeConfig(url="udp://127.0.0.1:5000", model="C12", endpoints=["udpout:127.0.0.1:14550"],
                              video_urls=[bad])  # fmt: skip
        with pytest.raises(CotConfigError, match="video URL"):
            config.check()
    assert check_text("video URL", "rtsp://127.0.0.1:8554/caméra") == "rtsp://127.0.0.1:8554/caméra"
    with pytest.raises(CotConfigError, match="at most"):
        check_text("CoT callsign", "x" * 300, 256)


def test_control_characters_in_text_become_replacement_characters() -> None:
    data = events(_sighting(url="rtsp://127.0.0.1/a\x01b"), uid="u\x00v", callsign="a\x1bb\ud800", now=1.7e9)
    vehicle = _parse_all(data)[0]
    assert vehicle.get("uid") == "u\ufffdv"
    assert vehicle.find("detail/contact").get("callsign") == "a\ufffdb\ufffd"


@pytest.mark.parametrize("lat, lon", [(0.0, 0.0), (math.nan, 8.0), (47.0, math.inf)])
def test_no_events_for_an_unknown_vehicle_position(lat: float, lon: float) -> None:
    assert events(_sighting(lat, lon), uid="u", callsign="c", now=1.7e9) == []


def _egm96_by_crs(lat: float, lon: float) -> float:
    """N from PROJ's CRS database (WGS84 + EGM96 height -> WGS84 3D), not the code's pipeline."""
    import pyproj.datadir
    from pyproj import Transformer

    grid = geoid.find_grid()
    assert grid is not None
    pyproj.datadir.append_data_dir(str(grid.parent))
    t = Transformer.from_crs("EPSG:4326+5773", "EPSG:4979", always_xy=True, only_best=True)
    return float(t.transform(lon, lat, 0.0)[2])


@pytest.mark.parametrize("lat, lon", [(-35.36, 149.16), (47.0, 8.0), (27.99, 86.93), (-8.0, 80.0), (60.0, -30.0)])
def test_hae_is_msl_plus_the_egm96_undulation(lat: float, lon: float) -> None:
    n = _egm96_by_crs(lat, lon)
    data = events(_sighting(lat, lon, alt=700.0), uid="u", callsign="c", now=1.7e9)
    vehicle, spi, shape = _parse_all(data)
    assert float(vehicle.find("point").get("hae")) == pytest.approx(700.0 + n, abs=0.01)
    assert float(spi.find("point").get("hae")) == pytest.approx(600.0 + _egm96_by_crs(lat + 2e-3, lon), abs=0.01)
    first = shape.find("detail/link").get("point").split(",")
    assert float(first[2]) == pytest.approx(600.0 + _egm96_by_crs(float(first[0]), float(first[1])), abs=0.06)
    if (lat, lon) == (-35.36, 149.16):
        assert n == pytest.approx(19.44, abs=0.01)  # the toolchain notes' figure for this point


def test_without_the_geoid_hae_is_unknown_not_msl(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setattr(geoid, "_default", [None])  # looked for, not found
    vehicle, spi, shape = _parse_all(events(_sighting(), uid="u", callsign="c", now=1.7e9))
    assert float(vehicle.find("point").get("hae")) == UNKNOWN
    assert float(spi.find("point").get("hae")) == UNKNOWN
    assert len(shape.find("detail/link").get("point").split(",")) == 2  # lat, lon: no height rather than MSL


def test_a_missing_grid_is_said_once(monkeypatch: pytest.MonkeyPatch, caplog: pytest.LogCaptureFixture) -> None:
    monkeypatch.setattr(geoid, "_default", [])
    monkeypatch.setattr(geoid, "find_grid", lambda: None)
    with caplog.at_level(logging.WARNING, "topgimbal.geo"):
        for _ in range(3):
            assert geoid.ellipsoid_height(LAT, LON, 100.0) is None
    assert caplog.text.count("no EGM96 geoid grid") == 1
