"""`mavlink --terrain DEM.tif`: CAMERA_FOV_STATUS's image centre lies on the DEM (height within
1 m) within 3 m of an independent ray cast, in QGroundControl's flow (REQUEST_MESSAGE 271 again
after each zoom change: hfov / vfov follow the zoom) and as a stream at a requested interval."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest
import rasterio
from pymavlink.dialects.v20 import common as ml

from topgimbal.geo import Geodetic, GridTerrain, LocalFrame
from topgimbal.geo.dem import load_dem
from topgimbal.geo.synthetic import write_dem

from .conftest import eventually

pytestmark = pytest.mark.loopback

CAMERA = 100
LAT0, LON0 = 47.0, 8.0
R = 6371008.8


@pytest.fixture(scope="module")
def dem(tmp_path_factory: pytest.TempPathFactory) -> Path:
    return write_dem(tmp_path_factory.mktemp("dem") / "hills.tif", LAT0, LON0)


def _cast(path: Path, lat: float, lon: float, alt: float, bearing: float, pitch: float) -> tuple[float, float, float]:
    """An independent cast: the raster's own bilinear heights, 0.1 m steps, then bisection."""
    with rasterio.open(path) as src:
        z, t = src.read(1).astype("float64"), src.transform

    def above(s: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        b, p = math.radians(bearing), math.radians(pitch)
        n, e, up = s * math.cos(p) * math.cos(b), s * math.cos(p) * math.sin(b), s * math.sin(p)
        la = lat + np.degrees(n / R)
        lo = lon + np.degrees(e / (R * math.cos(math.radians(lat))))
        u, v = (lo - t.c) / t.a - 0.5, (la - t.f) / t.e - 0.5
        c, r = np.floor(u).astype(int), np.floor(v).astype(int)
        fu, fv = u - c, v - r
        h = (
            z[r, c] * (1 - fu) * (1 - fv)
            + z[r, c + 1] * fu * (1 - fv)
            + z[r + 1, c] * (1 - fu) * fv
            + z[r + 1, c + 1] * fu * fv
        )
        return alt + up - (h - (n * n + e * e) / (2 * R)), la, lo

    s = np.arange(0.0, 1500.0, 0.1)
    g, _, _ = above(s)
    i = int(np.nonzero(g <= 0)[0][0])
    lo_s, hi_s = float(s[i - 1]), float(s[i])
    for _ in range(40):
        mid = 0.5 * (lo_s + hi_s)
        if above(np.array([mid]))[0][0] > 0:
            lo_s = mid
        else:
            hi_s = mid
    _, la, lo = above(np.array([hi_s]))
    return float(la[0]), float(lo[0]), hi_s


def _on_dem(terrain: GridTerrain, fov: object) -> tuple[float, float, float]:
    lat, lon, alt = fov.lat_image / 1e7, fov.lon_image / 1e7, fov.alt_image / 1000.0  # type: ignore[attr-defined]
    ground = terrain.height_m(lat, lon)
    assert ground is not None
    assert abs(alt - ground) <= 1.0  # the image centre lies on the DEM
    return lat, lon, alt


async def test_fov_status_image_centre_on_the_terrain_and_zoom_flow(rig_factory, dem: Path) -> None:
    rig = await rig_factory("SIP", terrain=str(dem))
    terrain = load_dem(dem)
    p, s = rig.peer, rig.sim
    autopilot = type(p)(sysid=1, compid=1)
    await autopilot.connect(rig.bridge.addresses[0][1])
    try:
        s.gimbal.angle("pitch", -28.0)
        s.gimbal.angle("yaw", 20.0)
        await eventually(lambda: abs(s.gimbal.pitch_deg + 28) < 0.01 and abs(s.gimbal.yaw_deg - 20) < 0.01)
        att = rig.bridge.cam
        await eventually(
            lambda: (
                att.attitude is not None
                and abs(att.attitude.pitch_deg + 28) < 0.01
                and abs(att.attitude.yaw_deg - 20) < 0.01
            )
        )
        lat, lon, alt, heading = LAT0 - 0.004, LON0 + 0.003, 640.0, 35.0
        home = 300.0
        autopilot.send(ml.MAVLink_attitude_message(0, 0.0, 0.0, math.radians(heading), 0, 0, 0))
        autopilot.send(ml.MAVLink_global_position_int_message(
            0, round(lat * 1e7), round(lon * 1e7), round(alt * 1000), round((alt - home) * 1000), 0, 0, 0, 0))  # fmt: skip
        await eventually(lambda: rig.bridge.vehicles.fix() is not None and rig.bridge.vehicles.yaw_deg is not None)
        fov = await p.request(CAMERA, 271, "CAMERA_FOV_STATUS")
        assert (fov.lat_camera, fov.lon_camera, fov.alt_camera) == (
            round(lat * 1e7),
            round(lon * 1e7),
            round(alt * 1000),
        )
        got = _on_dem(terrain, fov)
        a = att.attitude
        t_lat, t_lon, _ = _cast(dem, lat, lon, alt, heading + a.yaw_deg, a.pitch_deg)
        n, e, _ = LocalFrame(Geodetic(t_lat, t_lon, 0.0)).to_local(got[0], got[1], 0.0)
        assert math.hypot(n, e) <= 3.0
        assert got[2] > home + 5  # on a hill: flat ground at home altitude would be far off
        hfov_1x = fov.hfov
        # QGroundControl's flow: zoom, then ask for CAMERA_FOV_STATUS again
        assert (await p.ack(CAMERA, ml.MAV_CMD_SET_CAMERA_ZOOM, ml.ZOOM_TYPE_RANGE, 100)).result == 0
        await eventually(lambda: (rig.bridge.cam.client.state.zoom or type("z", (), {"value": 1})).value > 1)
        zoomed = await p.request(CAMERA, 271, "CAMERA_FOV_STATUS")
        assert zoomed.hfov < hfov_1x / 2 and zoomed.vfov < fov.vfov / 2
        _on_dem(terrain, zoomed)
        # a stream at a requested interval (5 Hz), then off
        assert (await p.ack(CAMERA, ml.MAV_CMD_SET_MESSAGE_INTERVAL, 271, 200_000)).result == 0
        seen = []
        while len(seen) < 3:
            seen.append(await p.wait("CAMERA_FOV_STATUS", timeout=30.0))  # a bound on a hang
        assert all(m.lat_image == zoomed.lat_image for m in seen)
        assert (await p.ack(CAMERA, ml.MAV_CMD_SET_MESSAGE_INTERVAL, 271, -1)).result == 0
    finally:
        autopilot.close()


async def test_without_terrain_the_image_centre_is_flat_ground_at_home(rig_factory) -> None:
    rig = await rig_factory("SIP")
    p, s = rig.peer, rig.sim
    autopilot = type(p)(sysid=1, compid=1)
    await autopilot.connect(rig.bridge.addresses[0][1])
    try:
        s.gimbal.angle("pitch", -45.0)
        await eventually(
            lambda: rig.bridge.cam.attitude is not None and abs(rig.bridge.cam.attitude.pitch_deg + 45) < 0.01
        )
        autopilot.send(ml.MAVLink_attitude_message(0, 0.0, 0.0, 0.0, 0, 0, 0))
        autopilot.send(ml.MAVLink_global_position_int_message(0, 470000000, 80000000, 600000, 100000, 0, 0, 0, 0))
        await eventually(lambda: rig.bridge.vehicles.fix() is not None)
        fov = await p.request(CAMERA, 271, "CAMERA_FOV_STATUS")
        assert fov.alt_image == 500000
        assert abs((fov.lat_image - 470000000) / 1e7 * math.pi / 180 * R - 100.0) < 1.0
    finally:
        autopilot.close()


async def test_tracked_point_geo_status_lies_on_the_terrain(rig_factory, dem: Path) -> None:
    """CAMERA_TRACKING_GEO_STATUS (276) locates the tracked point with the same core as 271: on the
    --terrain DEM (not flat ground at home), with the core's 1-sigma horizontal error in h_acc."""
    rig = await rig_factory("SIP", terrain=str(dem))
    terrain = load_dem(dem)
    p, s = rig.peer, rig.sim
    autopilot = type(p)(sysid=1, compid=1)
    await autopilot.connect(rig.bridge.addresses[0][1])
    try:
        s.gimbal.angle("pitch", -30.0)
        await eventually(lambda: abs(s.gimbal.pitch_deg + 30) < 0.01)
        cam = rig.bridge.cam
        await eventually(lambda: cam.attitude is not None and abs(cam.attitude.pitch_deg + 30) < 0.01)
        lat, lon, alt, home = LAT0 - 0.004, LON0 + 0.003, 640.0, 300.0
        autopilot.send(ml.MAVLink_attitude_message(0, 0.0, 0.0, math.radians(35.0), 0, 0, 0))
        autopilot.send(ml.MAVLink_global_position_int_message(
            0, round(lat * 1e7), round(lon * 1e7), round(alt * 1000), round((alt - home) * 1000), 0, 0, 0, 0))  # fmt: skip
        await eventually(lambda: rig.bridge.vehicles.fix() is not None and rig.bridge.vehicles.yaw_deg is not None)
        assert (await p.ack(CAMERA, ml.MAV_CMD_CAMERA_TRACK_POINT, 0.5, 0.5)).result == 0
        await eventually(lambda: rig.bridge.cameras[0].tracker.geo_message() is not None, what="a located target")
        geo = await p.request(CAMERA, 276, "CAMERA_TRACKING_GEO_STATUS")
        fov = await p.request(CAMERA, 271, "CAMERA_FOV_STATUS")
        assert geo.tracking_status == ml.CAMERA_TRACKING_STATUS_FLAGS_ACTIVE
        ground = terrain.height_m(geo.lat / 1e7, geo.lon / 1e7)
        assert ground is not None and abs(geo.alt - ground) <= 1.0 and geo.alt > home + 5
        assert math.isfinite(geo.h_acc) and geo.h_acc > 0 and geo.dist > 0
        # the point tracked at the picture's centre is the image centre CAMERA_FOV_STATUS gives
        n, e, _ = LocalFrame(Geodetic(fov.lat_image / 1e7, fov.lon_image / 1e7, 0.0)).to_local(
            geo.lat / 1e7, geo.lon / 1e7, 0.0
        )
        assert math.hypot(n, e) <= 3.0
        assert (await p.ack(CAMERA, ml.MAV_CMD_CAMERA_STOP_TRACKING)).result == 0
    finally:
        autopilot.close()
