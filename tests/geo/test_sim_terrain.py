"""`sim --terrain`: the simulated laser reads the true range along the gimbal's ray from the fed
vehicle position (checked against the tests' own fine-step cast), nothing beyond the model's
maximum range, flat ground without a terrain model; and `locate` agrees with it."""

from __future__ import annotations

from pathlib import Path

import pytest

from sim.conftest import DeviceHarness  # tests/sim's sans-I/O device harness
from topgimbal.geo import Attitude, Geodetic, Pointing, View, locate, ray
from topgimbal.geo.dem import load_dem
from topgimbal.protocol import Frame
from topgimbal.sim.terrain import TerrainGround

from .brute import BruteCaster
from .conftest import LAT0, LON0

pytestmark = pytest.mark.virtual


def only(frames: list[Frame]) -> Frame:
    assert len(frames) == 1, frames
    return frames[0]


@pytest.fixture(scope="module")
def ground(dem_path: Path) -> TerrainGround:
    return TerrainGround.load(dem_path)


def _harness(model: str, ground: TerrainGround, *, lat: float, lon: float, alt: float, heading: float) -> DeviceHarness:
    h = DeviceHarness(model)
    h.dev.state.terrain = ground
    h.ask("LAT", lat_deg=lat)
    h.ask("LON", lon_deg=lon)
    h.ask("ALT", alt_m=alt)
    if "AZI" in h.dialect.commands:
        h.ask("AZI", azimuth_deg=heading)
    else:  # SkyDroid has no AZI: the heading is the vehicle's yaw (FAI)
        h.dev.gimbal.vehicle.yaw = heading
    return h


@pytest.mark.parametrize(("yaw", "pitch", "alt"), [(0.0, -30.0, 520.0), (75.0, -12.0, 450.0), (-140.0, -55.0, 700.0)])
def test_lrf_reads_the_true_range_over_the_terrain(
    ground: TerrainGround, dem_path: Path, yaw: float, pitch: float, alt: float
) -> None:
    h = _harness("SIP", ground, lat=LAT0 - 0.002, lon=LON0 + 0.001, alt=alt, heading=20.0)
    h.dev.gimbal.yaw_axis.pos, h.dev.gimbal.pitch_axis.pos = yaw, pitch
    out = h.ask("LRF", action="single")
    assert [f.ident for f in out] == ["LRF", "LRF", "LAT", "LON"]
    laser = h.decode(out[1])["distance_m"]
    view = View(Geodetic(LAT0 - 0.002, LON0 + 0.001, alt), Attitude(yaw_deg=20.0), Pointing(yaw, pitch))
    truth = BruteCaster(dem_path).cast(LAT0 - 0.002, LON0 + 0.001, alt, ray(view), 1600, step_m=0.1)
    assert truth is not None
    assert laser == pytest.approx(truth, abs=0.5)  # the goal: within 0.5 m (it reports 0.1 m steps)
    assert abs(laser - truth) <= 0.06
    fix = locate(view, terrain=load_dem(dem_path))
    assert fix is not None and fix.range_m == pytest.approx(laser, abs=0.06)
    fused = locate(view, terrain=load_dem(dem_path), laser_range_m=laser)
    assert fused is not None and fused.source == "laser+terrain"
    lat = h.dialect.decode(out[2]).fields
    assert lat is not None and lat["lat_deg"] == pytest.approx(fused.lat_deg, abs=2e-6)


def test_no_answer_beyond_the_maximum_range_or_without_a_position(ground: TerrainGround) -> None:
    h = _harness("SIP", ground, lat=LAT0, lon=LON0, alt=900.0, heading=0.0)
    h.dev.gimbal.pitch_axis.pos = -8.0  # ~600 m up, 8 degrees down: ground far beyond 1500 m
    assert h.ask("LRF", action="single")[1].data == b"ERR"
    h.dev.gimbal.pitch_axis.pos = 10.0  # the sky
    assert h.ask("LRF", action="single")[1].data == b"ERR"
    fresh = DeviceHarness("SIP")
    fresh.dev.state.terrain = ground
    fresh.dev.gimbal.pitch_axis.pos = -45.0
    fresh.ask("ALT", alt_m=500.0)  # no LAT / LON: the ray has no start on the model
    assert fresh.ask("LRF", action="single")[1].data == b"ERR"


def test_c13_slr_on_terrain_and_its_100_m_limit(ground: TerrainGround) -> None:
    h = _harness("C13", ground, lat=LAT0, lon=LON0, alt=0.0, heading=0.0)
    below = ground.height_m(LAT0, LON0)
    assert below is not None
    h.ask("ALT", alt_m=below + 40.0)
    h.dev.gimbal.pitch_axis.pos = -90.0
    assert h.decode(only(h.ask("SLR", read=True)))["distance_m"] == pytest.approx(40.0, abs=0.1)
    h.ask("ALT", alt_m=below + 150.0)
    assert only(h.ask("SLR", read=True)).data != b""  # the error frame: nothing within 100 m
    assert h.dev.state.terrain is ground


def test_flat_ground_without_terrain_is_unchanged() -> None:
    h = DeviceHarness("C13")
    h.dev.gimbal.pitch_axis.pos = -30.0
    h.ask("ALT", alt_m=20.0)
    assert h.decode(only(h.ask("SLR", read=True)))["distance_m"] == pytest.approx(40.0)
