"""The geolocation core on a synthetic DEM: the exact cell-by-cell intersection agrees with an
independent fine-step march, the sources are chosen and named as documented, the footprint and
the frames behave."""

from __future__ import annotations

import math
import random
from pathlib import Path

import pytest

from topgimbal.geo import Attitude, Geodetic, GridTerrain, LocalFrame, Pointing, View, footprint, locate, ray
from topgimbal.geo.dem import DemError, load_dem

from .brute import BruteCaster
from .conftest import LAT0, LON0

pytestmark = pytest.mark.virtual


@pytest.fixture(scope="module")
def terrain(dem_path: Path) -> GridTerrain:
    return load_dem(dem_path)


def test_exact_intersection_agrees_with_a_brute_force_march(terrain: GridTerrain, dem_path: Path) -> None:
    brute = BruteCaster(dem_path)
    rng = random.Random(36)
    checked = 0
    for _ in range(60):
        frame = LocalFrame(Geodetic(LAT0, LON0, 0.0))
        start = frame.to_geodetic(rng.uniform(-800, 800), rng.uniform(-800, 800), 0.0)
        alt = (terrain.height_m(start.lat_deg, start.lon_deg) or 0.0) + rng.uniform(60, 300)
        view = View(
            Geodetic(start.lat_deg, start.lon_deg, alt),
            Attitude(rng.uniform(-5, 5), rng.uniform(-5, 5), rng.uniform(0, 360)),
            Pointing(rng.uniform(-180, 180), rng.uniform(-70, -5)),
        )
        fix = locate(view, terrain=terrain, max_range_m=2500)
        truth = brute.cast(start.lat_deg, start.lon_deg, alt, ray(view), 2500)
        if truth is None:
            assert fix is None or fix.range_m > 2400
            continue
        assert fix is not None and fix.source == "terrain"
        assert fix.range_m == pytest.approx(truth, abs=0.05)
        ground = terrain.height_m(fix.lat_deg, fix.lon_deg)
        assert ground is not None
        assert fix.alt_m == pytest.approx(ground, abs=0.05)  # heights above the ellipsoid: on the ground
        checked += 1
    assert checked >= 40


def test_a_thin_ridge_a_ten_metre_step_would_cross_is_found(terrain: GridTerrain, dem_path: Path) -> None:
    # a grazing ray just clipping the top of the ridge at north -100 m
    brute = BruteCaster(dem_path)
    top = terrain.height_m(LAT0 - 100 / 111195.0, LON0)
    assert top is not None
    view = View(Geodetic(LAT0 + 300 / 111195.0, LON0, top + 8.0), Attitude(yaw_deg=180.0), Pointing(0.0, -1.2))
    fix = locate(view, terrain=terrain)
    truth = brute.cast(view.position.lat_deg, view.position.lon_deg, view.position.alt_m, ray(view), 3000, step_m=0.05)
    assert fix is not None and truth is not None
    assert fix.range_m == pytest.approx(truth, abs=0.05)


def test_laser_and_terrain_are_fused_when_they_agree_and_the_laser_wins_otherwise(terrain: GridTerrain) -> None:
    view = View(Geodetic(LAT0, LON0, 600.0), Attitude(yaw_deg=30.0), Pointing(0.0, -40.0))
    dem = locate(view, terrain=terrain)
    assert dem is not None
    fused = locate(view, terrain=terrain, laser_range_m=dem.range_m + 0.8)
    assert fused is not None and fused.source == "laser+terrain"
    assert dem.range_m < fused.range_m < dem.range_m + 0.8
    assert fused.error_m < dem.error_m
    roof = locate(view, terrain=terrain, laser_range_m=dem.range_m - 40.0)
    assert roof is not None and roof.source == "laser"
    assert roof.range_m == pytest.approx(dem.range_m - 40.0)
    alone = locate(view, laser_range_m=250.0)
    assert alone is not None and alone.source == "laser" and alone.range_m == 250.0


def test_flat_ground_is_the_last_resort_and_the_sky_is_nothing(terrain: GridTerrain) -> None:
    view = View(Geodetic(LAT0, LON0, 400.0), Attitude(), Pointing(0.0, -30.0))
    flat = locate(view, ground_alt_m=300.0)
    assert flat is not None and flat.source == "flat"
    # 100 m / sin 30, and 5 mm more: the ground curves away by 173^2 / 2R under the ray
    assert flat.range_m == pytest.approx(200.0, abs=0.01) and flat.range_m > 200.0
    assert flat.alt_m == pytest.approx(300.0, abs=1e-6)
    assert locate(View(view.position, Attitude(), Pointing(0.0, 10.0)), terrain=terrain, ground_alt_m=300.0) is None
    assert locate(view) is None
    far = View(Geodetic(LAT0 + 0.2, LON0, 400.0), Attitude(), Pointing(0.0, -30.0))  # off the model
    off = locate(far, terrain=terrain, ground_alt_m=300.0)
    assert off is not None and off.source == "flat"


def test_the_error_estimate_grows_with_range_and_flatness_of_the_ray(terrain: GridTerrain) -> None:
    pos = Geodetic(LAT0, LON0 - 0.01, 500.0)
    steep = locate(View(pos, Attitude(), Pointing(0.0, -70.0)), terrain=terrain)
    shallow = locate(View(pos, Attitude(), Pointing(0.0, -15.0)), terrain=terrain)
    assert steep is not None and shallow is not None
    assert steep.error_m < shallow.error_m


def test_body_frame_angles_turn_with_the_vehicle_and_earth_frame_ones_do_not() -> None:
    pos = Geodetic(LAT0, LON0, 400.0)
    body = locate(View(pos, Attitude(yaw_deg=90.0), Pointing(0.0, -45.0)), ground_alt_m=300.0)
    earth = locate(
        View(pos, Attitude(yaw_deg=12.0, roll_deg=20.0), Pointing(90.0, -45.0, earth_frame=True)), ground_alt_m=300.0
    )
    assert body is not None and earth is not None
    assert body.bearing_deg == pytest.approx(90.0)
    assert earth.bearing_deg == pytest.approx(90.0)
    assert (body.lat_deg, body.lon_deg) == pytest.approx((earth.lat_deg, earth.lon_deg), abs=1e-9)
    # the vehicle rolled right by 20 degrees tilts a body-frame camera looking right 20 degrees down
    rolled = locate(View(pos, Attitude(roll_deg=20.0), Pointing(90.0, -25.0)), ground_alt_m=300.0)
    assert rolled is not None and rolled.elevation_deg == pytest.approx(-45.0, abs=1e-6)


def test_footprint_corners_of_a_camera_looking_straight_down() -> None:
    view = View(Geodetic(LAT0, LON0, 400.0), Attitude(), Pointing(0.0, -90.0), hfov_deg=60.0, vfov_deg=40.0)
    corners = footprint(view, ground_alt_m=300.0)
    assert all(c is not None for c in corners)
    frame = LocalFrame(view.position)
    local = [frame.to_local(c.lat_deg, c.lon_deg, c.alt_m) for c in corners if c is not None]
    half_w, half_h = 100 * math.tan(math.radians(30)), 100 * math.tan(math.radians(20))
    # pitch -90 with yaw 0: the picture's top is north, its right east
    assert [(round(n, 3), round(e, 3)) for n, e, _ in local] == [
        (round(half_h, 3), round(-half_w, 3)),
        (round(half_h, 3), round(half_w, 3)),
        (round(-half_h, 3), round(half_w, 3)),
        (round(-half_h, 3), round(-half_w, 3)),
    ]
    horizon = footprint(View(view.position, Attitude(), Pointing(0.0, -10.0), 60.0, 40.0), ground_alt_m=300.0)
    assert horizon[0] is None and horizon[2] is not None  # top corners look at the sky


def test_dem_reader_refuses_what_it_cannot_use(tmp_path: Path) -> None:
    import numpy as np
    import rasterio
    from affine import Affine

    utm = tmp_path / "utm.tif"
    with rasterio.open(
        utm,
        "w",
        driver="GTiff",
        width=4,
        height=4,
        count=1,
        dtype="float32",
        crs="EPSG:32632",
        transform=Affine(10, 0, 0, 0, -10, 0),
    ) as dst:
        dst.write(np.zeros((4, 4), dtype="float32"), 1)
    with pytest.raises(DemError, match="latitude/longitude"):
        load_dem(utm)
    junk = tmp_path / "junk.tif"
    junk.write_bytes(b"II*\x00not a tiff at all")
    with pytest.raises(DemError):
        load_dem(junk)
    with pytest.raises(DemError):
        load_dem(tmp_path / "missing.tif")


def test_holes_in_the_model_stop_the_ray(tmp_path: Path) -> None:
    nan = float("nan")
    rows = [[100.0] * 50 for _ in range(50)]
    for r in range(50):
        rows[r][25] = nan
    g = GridTerrain(rows, LAT0, LON0, -10 / 111195.0, 10 / (111195.0 * math.cos(math.radians(LAT0))))
    start = Geodetic(LAT0 - 250 / 111195.0, g.lon0_deg + 50 / (111195.0 * math.cos(math.radians(LAT0))), 300.0)
    east = View(start, Attitude(), Pointing(90.0, -20.0))  # ground ~550 m east, past the hole at 250 m
    assert locate(east, terrain=g) is None
    west = View(start, Attitude(), Pointing(-90.0, -80.0))
    hit = locate(west, terrain=g)
    assert hit is not None and hit.alt_m == pytest.approx(100.0, abs=0.01)
