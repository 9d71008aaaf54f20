"""Issue 41.2: one simulated world pose. At vehicle heading 30 (and on a pitched, rolled vehicle) the
rendered picture, the truth file and the laser's range and target solution describe the same
line of sight: the picture's target within a pixel of where the truth puts it, the laser's ground
point within 1 m of the one the truth's bearing and pitch give. (Before, a heading fed alone by
AZI reached only the laser: the picture and the truth looked 30 degrees off, 194 m on the ground
at 375 m.) The bridge's CAMERA_FOV_STATUS is checked against the same pose in
tests/mavlink/test_world_pose.py."""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np
import pytest

from topgimbal.sim import scene
from topgimbal.sim.targets import parse_spec
from topgimbal.sim.truth import truth_record
from topgimbal.sim.world import pose_of
from topgimbal.video.lens import stream_for
from topgimbal.video.render import Renderer
from topgimbal.video.snapshot import capture

from .conftest import DeviceHarness

pytestmark = pytest.mark.virtual

LAT, LON, ALT = 47.0, 8.0, 120.0
W, H = 640, 360


def picture_target_px(h: DeviceHarness) -> tuple[float, float]:
    """Where the target is drawn: the centroid of what changes when it is taken out of the scene."""
    hfov = stream_for(h.dev.model, "visible").hfov_deg
    assert hfov is not None
    state = replace(capture(h.dev, wall_s=0.0), osd=False)
    r = Renderer("visible", W, H, hfov)
    with_t = np.asarray(r.render(state).convert("L"), np.int16)
    without = np.asarray(r.render(replace(state, targets=())).convert("L"), np.int16)
    ys, xs = np.nonzero(np.abs(with_t - without) > 20)
    assert len(xs) > 20, "the target is not in the picture"
    return float(xs.mean()) + 0.5, float(ys.mean()) + 0.5


def ground_from_truth(rec: dict[str, object]) -> tuple[float, float]:
    """The flat-ground point (lat, lon) the truth's line of sight meets, ALT above it."""
    pitch, bearing = float(rec["pitch_deg"]), float(rec["yaw_deg"])  # type: ignore[arg-type]
    return scene.target_position(LAT, LON, bearing, pitch, ALT / math.sin(math.radians(-pitch)))


def metres(a: tuple[float, float], b: tuple[float, float]) -> float:
    n = (a[0] - b[0]) * 111_195.0
    e = (a[1] - b[1]) * 111_195.0 * math.cos(math.radians(LAT))
    return math.hypot(n, e)


def test_sip_heading_30_picture_truth_and_laser_agree() -> None:
    h = DeviceHarness("SIP")
    for ident, values in (("LAT", {"lat_deg": LAT}), ("LON", {"lon_deg": LON}), ("ALT", {"alt_m": ALT})):
        h.ask(ident, **values)
    h.ask("AZI", azimuth_deg=30.0)  # the heading alone, as ArduPilot and the bridge feed a SIP
    h.dev.gimbal.angle("yaw", 5.0)
    h.dev.gimbal.angle("pitch", -30.0)
    h.advance(10.0)
    rec = truth_record(h.dev)
    assert rec["vehicle_deg"] == [30.0, 0.0, 0.0]
    assert rec["yaw_deg"] == pytest.approx(35.0, abs=1e-3)  # body 5 + heading 30
    # A target a little off the axis: the picture draws it where the truth projects it.
    h.dev.state.targets = (parse_spec("bearing=39,elevation=-27,size=2,contrast=0.9"),)
    rec = truth_record(h.dev)
    tg = rec["targets"][0]  # type: ignore[index]
    px, py = picture_target_px(h)
    print(f"SIP heading 30: picture vs truth {px - tg['x'] * W:+.2f}, {py - tg['y'] * H:+.2f} px")
    assert abs(px - tg["x"] * W) <= 1.0 and abs(py - tg["y"] * H) <= 1.0, (px, py, tg)
    # The laser's range and target solution are those of the truth's line of sight.
    out = h.ask("LRF", action="single")
    assert [f.ident for f in out] == ["LRF", "LRF", "LAT", "LON"]
    d = h.decode(out[1])["distance_m"]
    assert d == pytest.approx(ALT / math.sin(math.radians(30.0)), abs=0.1)
    laser = (h.decode(out[2])["lat_deg"], h.decode(out[3])["lon_deg"])
    print(f"SIP heading 30: laser vs truth's ground point {metres(laser, ground_from_truth(rec)):.2f} m")
    assert metres(laser, ground_from_truth(rec)) <= 1.0
    # ... and that line is the heading's: 35 degrees from north, not the body's 5 (the old picture)
    north = scene.target_position(LAT, LON, 5.0, -30.0, d)
    assert metres(laser, north) > 100.0


def test_a_yaw_lock_holds_its_bearing_while_the_heading_changes() -> None:
    h = DeviceHarness("SIP")
    h.ask("AZI", azimuth_deg=0.0)
    h.dev.gimbal.set_mode("lock")
    h.dev.gimbal.angle("yaw", 20.0, frame="earth")
    h.advance(5.0)
    assert truth_record(h.dev)["yaw_deg"] == pytest.approx(20.0, abs=1e-3)
    h.ask("AZI", azimuth_deg=30.0)  # the vehicle turned right: a lock turns the gimbal left
    h.advance(5.0)
    rec = truth_record(h.dev)
    assert rec["yaw_deg"] == pytest.approx(20.0, abs=1e-3)
    assert h.dev.gimbal.yaw_deg == pytest.approx(-10.0, abs=1e-3)


def test_c12_on_a_pitched_rolled_vehicle_heading_30_picture_and_truth_agree() -> None:
    h = DeviceHarness("C12")
    h.ask("FAE", state="on")
    h.ask("FAI", yaw_deg=30.0, pitch_deg=5.0, roll_deg=3.0)
    pose = pose_of(h.dev.gimbal, h.dev.state.position)
    assert pose.vehicle == pytest.approx((30.0, 5.0, 3.0))
    h.dev.gimbal.angle("yaw", -8.0)
    h.dev.gimbal.angle("pitch", -15.0)
    h.advance(10.0)
    rec = truth_record(h.dev)
    assert rec["yaw_deg"] == pytest.approx(22.0, abs=1e-3)
    assert rec["pitch_deg"] == pytest.approx(-15.0, abs=1e-3)  # stabilised from the horizon
    assert rec["roll_deg"] == pytest.approx(0.0, abs=1e-3)
    h.dev.state.targets = (parse_spec("bearing=18,elevation=-12,size=2,contrast=0.9"),)
    rec = truth_record(h.dev)
    tg = rec["targets"][0]  # type: ignore[index]
    px, py = picture_target_px(h)
    print(f"C12 heading 30 pitch 5 roll 3: picture vs truth {px - tg['x'] * W:+.2f}, {py - tg['y'] * H:+.2f} px")
    assert abs(px - tg["x"] * W) <= 1.0 and abs(py - tg["y"] * H) <= 1.0, (px, py, tg)
