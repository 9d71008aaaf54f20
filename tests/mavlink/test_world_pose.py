"""Issue 41.2 through the bridge: an autopilot at heading 30 feeds a SIP (the heading alone, AZI, as
ArduPilot does); CAMERA_FOV_STATUS's image centre (and KLV's frame centre and CoT's sensor point),
the simulated laser's ground point and the simulator's truth (which the picture is drawn from: tests/sim/test_world_pose.py) agree within
1 m. Before, the truth and the picture looked along the body yaw while the laser and
CAMERA_FOV_STATUS counted the heading: 194 m apart on the ground at this range."""

from __future__ import annotations

import asyncio
import contextlib
import math
from typing import Any

import pytest
from pymavlink.dialects.v20 import common as ml

from topgimbal.sim import scene
from topgimbal.sim.handlers.ranging import measure
from topgimbal.sim.truth import truth_record

from .conftest import eventually
from .virtual import MemPeer

pytestmark = pytest.mark.virtual

CAMERA = 100
LAT, LON, ALT = 47.0, 8.0, 120.0  # home at 0 m: the simulator's flat ground


def metres(a: tuple[float, float], b: tuple[float, float]) -> float:
    n = (a[0] - b[0]) * 111_195.0
    e = (a[1] - b[1]) * 111_195.0 * math.cos(math.radians(LAT))
    return math.hypot(n, e)


async def fly(autopilot: MemPeer, heading_deg: float) -> None:
    """The autopilot's attitude and position at 10 Hz, standing still at `heading_deg`."""
    i = 0
    while True:
        autopilot.send(ml.MAVLink_attitude_message(i * 100, 0.0, 0.0, math.radians(heading_deg), 0, 0, 0))
        autopilot.send(ml.MAVLink_global_position_int_message(
            i * 100, round(LAT * 1e7), round(LON * 1e7), round(ALT * 1000), round(ALT * 1000), 0, 0, 0,
            round(heading_deg * 100)))  # fmt: skip
        i += 1
        await asyncio.sleep(0.1)


async def test_fov_status_laser_and_truth_agree_at_heading_30(vrig_maker: Any) -> None:
    vrig = await vrig_maker("SIP")
    sim = vrig.sim
    autopilot = await MemPeer(sysid=1, compid=1).join(vrig.link)
    flying = asyncio.ensure_future(fly(autopilot, 30.0))
    try:
        pos = sim.device.state.position
        await eventually(lambda: pos.alt_m == ALT and pos.azimuth_deg == pytest.approx(30.0), 10.0, "the feeds")
        sim.gimbal.angle("yaw", 5.0)
        sim.gimbal.angle("pitch", -30.0)
        cam = vrig.bridge.cam
        await eventually(
            lambda: (
                cam.attitude is not None
                and abs(cam.attitude.yaw_deg - 5.0) < 0.01
                and abs(cam.attitude.pitch_deg + 30.0) < 0.01
            ),
            10.0,
            "the gimbal on its angles, as the bridge hears it",
        )
        fov = await vrig.peer.request(CAMERA, 271, "CAMERA_FOV_STATUS")
        image = (fov.lat_image / 1e7, fov.lon_image / 1e7)
        rec = truth_record(sim.device)
        assert rec["yaw_deg"] == pytest.approx(35.0, abs=0.01)  # the picture's axis: body 5 + heading 30
        d = measure(sim.device.state)
        assert d == pytest.approx(ALT / math.sin(math.radians(30.0)), abs=0.1)
        laser = scene.target_position(LAT, LON, float(rec["yaw_deg"]), float(rec["pitch_deg"]), d)
        print(f"heading 30: FOV_STATUS image centre {metres(image, laser):.2f} m from the laser's point")
        assert metres(image, laser) <= 1.0, (image, laser)
        body_only = scene.target_position(LAT, LON, 5.0, -30.0, d)  # what the picture showed before
        assert metres(image, body_only) > 100.0
        # KLV's frame centre (ST 0601 tags 23, 24) and Cursor-on-Target's sensor point say the same
        view = vrig.bridge.cameras[0].view
        klv = view.klv_values()
        assert klv is not None and metres((klv[23], klv[24]), laser) <= 1.0
        assert klv[21] == pytest.approx(d, abs=1.0)  # slant range
        sighting = view.sighting()
        assert sighting is not None and sighting.target is not None
        assert metres((sighting.target.lat_deg, sighting.target.lon_deg), laser) <= 1.0
        assert sighting.azimuth_deg == pytest.approx(float(rec["yaw_deg"]), abs=0.01)
    finally:
        flying.cancel()
        with contextlib.suppress(asyncio.CancelledError):
            await flying
        autopilot.close()
