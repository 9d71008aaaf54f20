"""Issue 41.4: CAMERA_TRACKING_IMAGE_STATUS's box stays on a moving target. The camera's own tracker
keeps the target centred (the simulator's truth); the bridge's box, which QGroundControl draws on
the video, must be within 0.05 of the picture of the target's true place in at least 90 % of the
reports, for a target crossing at 10 deg/s in either direction (it drifted a median 0.75 away
when the target crossed towards the side it was picked on: the estimate assumed a still target).
Virtual time: the simulator, the bridge and the ground station on memory links."""

from __future__ import annotations

import asyncio
import math
from typing import Any

import pytest
from pymavlink.dialects.v20 import common as ml

from topgimbal.sim.targets import parse_spec
from topgimbal.sim.truth import truth_record

from .conftest import eventually

pytestmark = pytest.mark.virtual

CAMERA = 100
STATUS = 275


def box_centre(m: Any) -> tuple[float, float]:
    if m.tracking_mode == ml.CAMERA_TRACKING_MODE_POINT:
        return m.point_x, m.point_y
    return (m.rec_top_x + m.rec_bottom_x) / 2, (m.rec_top_y + m.rec_bottom_y) / 2


async def box_errors(vrig: Any, start_deg: float, speed_deg_s: float, *, point: bool, seconds: float) -> list[float]:
    """Track a target crossing from `start_deg` off the axis; the distance (picture fractions)
    between each ACTIVE report's box and the target's true place in the picture."""
    s, p = vrig.sim, vrig.peer
    await eventually(lambda: vrig.bridge.cam.attitude is not None, what="attitude from the camera")
    t0 = s.device.now - s.device.state.camera.booted_at
    heading = 0.0 if speed_deg_s >= 0 else 180.0  # 0 moves right, 180 left
    s.device.state.targets = (
        parse_spec(f"bearing={start_deg - speed_deg_s * t0:.4f},elevation=-3,speed={abs(speed_deg_s)},"
                   f"heading={heading},size=2"),
    )  # fmt: skip
    tg = truth_record(s.device)["targets"][0]
    x, y = tg["x"], tg["y"]
    if point:
        ack = await p.ack(CAMERA, ml.MAV_CMD_CAMERA_TRACK_POINT, x, y, 0.03)
    else:
        ack = await p.ack(CAMERA, ml.MAV_CMD_CAMERA_TRACK_RECTANGLE, x - 0.03, y - 0.05, x + 0.03, y + 0.05)
    assert ack.result == 0
    assert (await p.ack(CAMERA, ml.MAV_CMD_SET_MESSAGE_INTERVAL, STATUS, 100_000)).result == 0
    got: list[tuple[Any, dict[str, Any]]] = []

    def heard(m: Any) -> bool:
        if m.get_srcComponent() == CAMERA:
            got.append((m, truth_record(s.device)))
        return False

    watch = asyncio.ensure_future(p.wait("CAMERA_TRACKING_IMAGE_STATUS", heard, timeout=seconds + 5))
    await asyncio.sleep(seconds)
    watch.cancel()
    assert (await p.ack(CAMERA, ml.MAV_CMD_CAMERA_STOP_TRACKING)).result == 0
    errors = []
    for m, t in got:
        assert t["tracking"] == "tracking", "the simulated camera lost the target"
        assert m.tracking_status == ml.CAMERA_TRACKING_STATUS_FLAGS_ACTIVE
        cx, cy = box_centre(m)
        tx, ty = t["targets"][0]["x"], t["targets"][0]["y"]
        errors.append(math.hypot(cx - tx, cy - ty))
    assert len(errors) >= seconds * 10 * 0.8
    return errors


@pytest.mark.parametrize(
    ("model", "start_deg", "speed_deg_s", "point"),
    [
        ("SIP", -6.0, 10.0, False),  # picked left of the axis, crossing right: the box drifted left
        ("SIP", 6.0, -10.0, True),
        ("C12", -6.0, 10.0, True),
        ("C12", 6.0, -10.0, True),  # the C12 tracks a point only (its GOT)
    ],
)
async def test_the_box_stays_on_a_moving_target(
    vrig_maker: Any, model: str, start_deg: float, speed_deg_s: float, point: bool
) -> None:
    vrig = await vrig_maker(model)
    errors = await box_errors(vrig, start_deg, speed_deg_s, point=point, seconds=6.0)
    within = sum(e <= 0.05 for e in errors) / len(errors)
    errors.sort()
    print(f"{model} {start_deg:+g} deg at {speed_deg_s:+g} deg/s: {within:.0%} of {len(errors)} within 0.05, "
          f"median {errors[len(errors) // 2]:.3f}, max {errors[-1]:.3f}")  # fmt: skip
    assert within >= 0.9, f"{within:.0%} within 0.05 (median {errors[len(errors) // 2]:.3f})"


async def test_no_box_while_the_companion_loop_searches(vrig_maker: Any) -> None:
    """With the companion loop (a model without a tracker), the box is where the loop found the
    target in the newest picture; while it searches, ACTIVE without a box: none where no target is."""
    from types import SimpleNamespace

    from topgimbal.mavlink.camera_tracking import Tracker

    vrig = await vrig_maker("C10")
    tracker = Tracker(vrig.bridge.cam, fov=lambda: (60.0, 34.0), companion_url="rtsp://127.0.0.1:8554/unused")
    assert tracker.companion_url is not None  # the C10 has no tracker of its own
    tracker.state = (2, (0.4, 0.4, 0.5, 0.5))
    tracker._picture_size = (640, 360)
    loop: Any = SimpleNamespace(state="tracking", vision=SimpleNamespace(centre=(400.0, 90.0)))
    tracker.companion = loop
    m = tracker.status_message()
    assert m.tracking_status == ml.CAMERA_TRACKING_STATUS_FLAGS_ACTIVE
    assert box_centre(m) == pytest.approx((400 / 640, 90 / 360))  # measured, not the box asked for
    loop.state = "searching"
    m = tracker.status_message()
    assert m.tracking_status == ml.CAMERA_TRACKING_STATUS_FLAGS_ACTIVE and m.target_data == 0
    assert math.isnan(m.rec_top_x) and math.isnan(m.point_x)
    loop.state = "lost"
    assert tracker.status_message().tracking_status == ml.CAMERA_TRACKING_STATUS_FLAGS_ERROR
