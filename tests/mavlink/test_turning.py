"""Earth-frame pointing while the vehicle turns (issue 32, item 1), without SITL: a fake autopilot
streams AUTOPILOT_STATE_FOR_GIMBAL_DEVICE with a turning yaw and the same earth-frame
GIMBAL_DEVICE_SET_ATTITUDE at 50 Hz, as ArduPilot's AP_Mount_MAVLink does for a yaw lock or an ROI.
The error is measured on the simulated camera's own attitude: its body yaw plus the vehicle's
heading at that instant, against the earth bearing asked for.

The goal (p95 <= 1 deg at 6 deg/s, <= 3 deg at 20 deg/s) is the issue's. The C12's motors turn at
12.7 deg/s at most, so 20 deg/s is measured on the SIP (99 deg/s): no bridge can make a camera
counter-turn faster than its motors."""

from __future__ import annotations

import asyncio
import math
import statistics
from typing import Any

import pytest
from pymavlink.dialects.v20 import common as ml

from topgimbal.clock import monotonic
from topgimbal.mavlink.quaternion import from_euler_deg

from .conftest import NAN, Peer, eventually
from .figures import percentile, wrap180

pytestmark = pytest.mark.external

GIMBAL = 154
EARTH = ml.GIMBAL_DEVICE_FLAGS_ROLL_LOCK | ml.GIMBAL_DEVICE_FLAGS_PITCH_LOCK | ml.GIMBAL_DEVICE_FLAGS_YAW_LOCK
STREAM_HZ = 50.0


async def fly_turn(
    r: Any, rate_deg_s: float, target_deg: float, seconds: float, reported_rate_scale: float | None = None
) -> list[float]:
    """Stream a turn at `rate_deg_s` that keeps the earth-frame target inside the camera's yaw range
    (starting at target + 60 deg, the body yaw goes from -60 to +60 for a 120 deg turn); the
    signed earth yaw errors (degrees, > 0 right of the target) sampled at the stream's rate once
    the camera has caught up. `reported_rate_scale`: the autopilot also reports its yaw rate
    (angular_velocity_z) as that many times the true one; None: no rate field (NaN)."""
    autopilot = await Peer(sysid=1, compid=1).connect(r.bridge.addresses[0][1])
    g = r.sim.gimbal
    span_deg = rate_deg_s * seconds
    start_deg = target_deg + span_deg / 2  # yawing negative: body yaw = target - heading goes up
    q_target = list(from_euler_deg(0.0, -20.0, target_deg))
    errors: list[float] = []
    try:
        boot = monotonic()  # the autopilot's boot clock runs on, whatever it does

        def heading(t: float) -> float:
            return wrap180(start_deg - rate_deg_s * t)

        def send(t: float, turning: bool = True) -> None:
            q = list(from_euler_deg(0.0, 0.0, heading(t)))
            reported = NAN if reported_rate_scale is None else math.radians(-rate_deg_s * reported_rate_scale * turning)
            autopilot.send(ml.MAVLink_autopilot_state_for_gimbal_device_message(
                1, GIMBAL, int((monotonic() - boot) * 1e6), q, 0, NAN, NAN, NAN, 0, NAN,
                ml.ESTIMATOR_ATTITUDE, ml.MAV_LANDED_STATE_IN_AIR, reported))  # fmt: skip
            autopilot.send(ml.MAVLink_gimbal_device_set_attitude_message(1, GIMBAL, EARTH, q_target, NAN, NAN, NAN))

        # hold the start heading until the camera is there
        t0 = monotonic()
        while abs(wrap180(heading(0) + g.yaw_deg - target_deg)) > 0.5 or abs(g.pitch_deg + 20) > 0.5:
            send(0.0, turning=False)
            await asyncio.sleep(1 / STREAM_HZ)
            assert monotonic() - t0 < 30, f"the camera did not reach the start (yaw {g.yaw_deg:.1f})"
        t0 = monotonic()
        while (t := monotonic() - t0) < seconds:
            send(t)
            await asyncio.sleep(1 / STREAM_HZ)
            now = monotonic() - t0
            if now > 1.0:  # the first second: the camera catches the turn
                r.sim.sync()  # where the camera points now, not at the simulator's last step
                errors.append(wrap180(heading(now) + g.yaw_deg - target_deg))
    finally:
        autopilot.close()
    return errors


# serial: a real-time closed loop scored in degrees; make test runs it apart from the parallel pass
@pytest.mark.serial
@pytest.mark.parametrize(("model", "rate_deg_s", "p95_deg"), [("C12", 6.0, 1.0), ("SIP", 20.0, 3.0)])
async def test_earth_yaw_follows_a_turning_vehicle(
    rig_factory: Any, model: str, rate_deg_s: float, p95_deg: float
) -> None:
    r = await rig_factory(model, role="device")
    await eventually(lambda: r.bridge.cam.answering, 10, "camera answering")
    errors = [abs(e) for e in await fly_turn(r, rate_deg_s, 30.0, 6.0)]
    p50, p95, top = percentile(errors, 50), percentile(errors, 95), max(errors)
    print(f"{model} {rate_deg_s:g} deg/s: earth yaw error p50 {p50:.2f} p95 {p95:.2f} max {top:.2f} deg "
          f"({len(errors)} samples)")  # fmt: skip
    assert len(errors) > 100
    assert p95 <= p95_deg, f"earth yaw error p95 {p95:.2f} deg at {rate_deg_s:g} deg/s (goal {p95_deg:g})"
    # the stream stops while the camera was counter-turning by rate: it stops on the last angle
    assert r.bridge.pointer.rate_follow_sent > 0
    yaw_axis = r.sim.gimbal.yaw_axis
    await eventually(lambda: yaw_axis.mode == "angle" and yaw_axis.vel == 0.0, 5, "stopped on an angle command")
    first = r.sim.gimbal.yaw_deg
    await asyncio.sleep(0.5)
    assert abs(r.sim.gimbal.yaw_deg - first) < 0.05, "the camera keeps turning after the set-points stopped"


async def test_a_vehicle_standing_still_gets_angle_commands(rig_factory: Any) -> None:
    r = await rig_factory("C12", role="device")
    await eventually(lambda: r.bridge.cam.answering, 10, "camera answering")
    errors = [abs(e) for e in await fly_turn(r, 0.0, 30.0, 2.0)]
    assert max(errors) < 0.5
    assert r.bridge.pointer.rate_follow_sent == 0


@pytest.mark.serial
async def test_a_reported_yaw_rate_that_is_off_leaves_no_steady_error(rig_factory: Any) -> None:
    """ArduPilot SITL's AUTOPILOT_STATE_FOR_GIMBAL_DEVICE said angular_velocity_z 6.78 deg/s in a
    turn its heading made at 6.0 (13 % high). Fed forward as it came, it left the camera 0.24 deg
    ahead of the bearing for the whole turn (off / FOLLOW_GAIN_PER_S: 0.78 / 3 = 0.26); the follow
    loop's integral takes that out within a few seconds."""
    r = await rig_factory("C12", role="device")
    await eventually(lambda: r.bridge.cam.answering, 10, "camera answering")
    errors = await fly_turn(r, 6.0, 30.0, 8.0, reported_rate_scale=1.13)
    late = errors[len(errors) // 2 :]  # the second half: the integral has settled (about 2.6 s)
    mean = statistics.fmean(late)
    print(f"reported rate 13 % high: signed earth yaw error, second half, mean {mean:+.3f} deg "
          f"({len(late)} samples); integral {r.bridge.pointer.follow_integral_deg_s:+.2f} deg/s")  # fmt: skip
    assert len(late) > 50
    assert abs(mean) <= 0.1, f"a steady error of {mean:+.2f} deg: the fed-forward rate's excess is not taken out"
