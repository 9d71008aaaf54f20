"""What the bridge puts in its ST 0601 packets (issue 41 items 3 and 12), read back by klvdata:
the sensor angles (tags 18-20) relative to the platform's axes, so that composing platform then
sensor rotations as ST 0601 says gives the camera's own line of sight; and no 0, 0 position before
the autopilot has a GPS fix. Virtual tier: a memory:// rig with a pymavlink autopilot."""

from __future__ import annotations

import math
from typing import Any

import klvdata
import numpy as np
import pytest
from pymavlink.dialects.v20 import common as ml

from topgimbal.outputs.klv import packet

from .conftest import eventually
from .virtual import MemPeer

pytestmark = pytest.mark.virtual


def parsed(data: bytes) -> dict[str, float]:
    (ls,) = list(klvdata.StreamParser(data))
    return {str(item.LDSName): item.value.value for item in ls.items.values() if hasattr(item, "LDSName")}


def zyx(yaw_deg: float, pitch_deg: float, roll_deg: float) -> np.ndarray:
    """Body-to-NED rotation, written out here (not the product's): yaw about z, then pitch about
    the new y, then roll about the new x."""
    y, p, r = np.radians([yaw_deg, pitch_deg, roll_deg])
    rz = np.array([[np.cos(y), -np.sin(y), 0], [np.sin(y), np.cos(y), 0], [0, 0, 1]])
    ry = np.array([[np.cos(p), 0, np.sin(p)], [0, 1, 0], [-np.sin(p), 0, np.cos(p)]])
    rx = np.array([[1, 0, 0], [0, np.cos(r), -np.sin(r)], [0, np.sin(r), np.cos(r)]])
    return rz @ ry @ rx


def los_from_tags(v: dict[str, float]) -> np.ndarray:
    """The line of sight (NED unit vector) a player composes from tags 5-7 and 18-20."""
    platform = zyx(v["Platform Heading Angle"], v["Platform Pitch Angle"], v["Platform Roll Angle"])
    sensor = zyx(v["Sensor Relative Azimuth Angle"], v["Sensor Relative Elevation Angle"],
                 v["Sensor Relative Roll Angle"])  # fmt: skip
    return platform @ sensor @ np.array([1.0, 0.0, 0.0])


def los(bearing_deg: float, elevation_deg: float) -> np.ndarray:
    b, e = math.radians(bearing_deg), math.radians(elevation_deg)
    return np.array([math.cos(e) * math.cos(b), math.cos(e) * math.sin(b), -math.sin(e)])


async def _rig(vrig_maker: Any) -> tuple[Any, MemPeer, Any]:
    vrig = await vrig_maker("C12")
    await eventually(lambda: vrig.bridge.cam.answering, 10, "camera answering")
    autopilot = await MemPeer(sysid=1, compid=1).join(vrig.link)
    return vrig, autopilot, vrig.bridge.cameras[0].view


def _position(lat: float, lon: float, alt_m: float, hdg_deg: float) -> Any:
    return ml.MAVLink_global_position_int_message(1000, round(lat * 1e7), round(lon * 1e7), round(alt_m * 1000),
                                                  120 * 1000, 0, 0, 0, round(hdg_deg * 100))  # fmt: skip


async def test_no_position_before_the_gps_fix(vrig_maker: Any) -> None:
    vrig, autopilot, view = await _rig(vrig_maker)
    autopilot.send(ml.MAVLink_attitude_message(0, 0.0, 0.0, math.radians(30), 0, 0, 0))
    autopilot.send(_position(0.0, 0.0, 0.0, 30.0))  # what an autopilot sends before its fix
    await eventually(lambda: vrig.bridge.vehicles.fix() is not None and vrig.bridge.cam.attitude is not None, 5)
    values = view.klv_values()
    assert values is not None
    for tag in (13, 14, 15, 21, 23, 24, 25):
        assert values[tag] is None, f"tag {tag} = {values[tag]} before the fix"
    v = parsed(packet(1, values))
    assert "Sensor Latitude" not in v and "Sensor Longitude" not in v and "Frame Center Latitude" not in v
    assert v["Platform Heading Angle"] == pytest.approx(30.0, abs=0.01)  # what is known still goes
    autopilot.send(_position(-35.3632, 149.1652, 700.0, 30.0))
    await eventually(lambda: (view.klv_values() or {}).get(13) is not None, 5, "the fix")
    v = parsed(packet(1, view.klv_values() or {}))
    assert v["Sensor Latitude"] == pytest.approx(-35.3632, abs=1e-6)
    assert v["Sensor Longitude"] == pytest.approx(149.1652, abs=1e-6)
    autopilot.close()


@pytest.mark.parametrize(
    ("roll", "pitch", "heading", "cam_yaw", "cam_pitch"),
    [(2.0, -3.0, 30.0, 20.0, -35.0), (-15.0, 12.0, 300.0, -60.0, -20.0), (20.0, 20.0, 170.0, 80.0, -20.0),
     (0.0, 0.0, 90.0, 10.0, -30.0)],
)  # fmt: skip
async def test_sensor_angles_compose_to_the_cameras_line_of_sight(
    vrig_maker: Any, roll: float, pitch: float, heading: float, cam_yaw: float, cam_pitch: float
) -> None:
    vrig, autopilot, view = await _rig(vrig_maker)
    attitude = ml.MAVLink_attitude_message(0, math.radians(roll), math.radians(pitch), math.radians(heading), 0, 0, 0)
    g = vrig.sim.gimbal
    g.angle("yaw", cam_yaw)
    g.angle("pitch", cam_pitch)
    await eventually(lambda: vrig.bridge.cam.attitude is not None and abs(vrig.bridge.cam.attitude.yaw_deg - cam_yaw)
                     < 0.01 and abs(vrig.bridge.cam.attitude.pitch_deg - cam_pitch) < 0.01, 10)  # fmt: skip
    autopilot.send(attitude)  # fresh after the camera's turn
    autopilot.send(_position(-35.3632, 149.1652, 700.0, heading))
    await eventually(lambda: view.klv_values() is not None, 5, "the fix")
    values = view.klv_values()
    assert values is not None
    v = parsed(packet(1, values))
    # the camera's own line of sight: yaw from the heading, pitch from the horizon (stabilised)
    want = los(heading + cam_yaw, cam_pitch)
    got = los_from_tags(v)
    err_deg = math.degrees(math.acos(max(-1.0, min(1.0, float(got @ want)))))
    # the differences of earth angles (what was sent before) miss it by degrees once the platform tilts
    naive = los_from_tags({**v, "Sensor Relative Azimuth Angle": cam_yaw % 360,
                           "Sensor Relative Elevation Angle": cam_pitch - pitch, "Sensor Relative Roll Angle": 0.0})  # fmt: skip
    naive_deg = math.degrees(math.acos(max(-1.0, min(1.0, float(naive @ want)))))
    print(f"platform r{roll:g} p{pitch:g} h{heading:g}: line of sight {err_deg:.4f} deg (naive {naive_deg:.2f} deg)")
    assert err_deg < 0.01
    if roll or pitch:
        assert naive_deg > 0.5
    autopilot.close()
