"""Earth-frame set-points from an autopilot's gimbal manager (ArduPilot MNT1_TYPE 6, PX4): the
vehicle's attitude comes in AUTOPILOT_STATE_FOR_GIMBAL_DEVICE, not ATTITUDE."""

from __future__ import annotations

import logging
import math
from typing import Any

import pytest
from pymavlink.dialects.v20 import common as ml

from topgimbal.mavlink.quaternion import from_euler_deg

from .conftest import NAN, Peer, eventually

pytestmark = pytest.mark.external

GIMBAL = 154
# What ArduPilot's AP_Mount_MAVLink streams for a yaw-locked (earth-frame) target.
EARTH = ml.GIMBAL_DEVICE_FLAGS_ROLL_LOCK | ml.GIMBAL_DEVICE_FLAGS_PITCH_LOCK | ml.GIMBAL_DEVICE_FLAGS_YAW_LOCK


def autopilot_state(roll_deg: float, pitch_deg: float, yaw_deg: float) -> Any:
    q = list(from_euler_deg(roll_deg, pitch_deg, yaw_deg))
    return ml.MAVLink_autopilot_state_for_gimbal_device_message(
        1, GIMBAL, 123456, q, 0, 0.0, 0.0, 0.0, 0, 0.0, ml.ESTIMATOR_ATTITUDE, ml.MAV_LANDED_STATE_ON_GROUND, NAN
    )


def set_attitude(flags: int, roll_deg: float, pitch_deg: float, yaw_deg: float) -> Any:
    q = list(from_euler_deg(roll_deg, pitch_deg, yaw_deg))
    return ml.MAVLink_gimbal_device_set_attitude_message(1, GIMBAL, flags, q, NAN, NAN, NAN)


async def test_attitude_from_autopilot_state_for_gimbal_device(rig_factory: Any) -> None:
    r = await rig_factory("C12", role="device")
    s, vehicles = r.sim, r.bridge.vehicles
    autopilot = await Peer(sysid=1, compid=1).connect(r.bridge.addresses[0][1])
    try:
        assert vehicles.attitude_deg() is None and vehicles.yaw_deg is None
        autopilot.send(autopilot_state(3.0, -4.0, 40.0))
        await eventually(lambda: vehicles.attitude_deg() is not None, 5, "attitude heard")
        roll, pitch, yaw = vehicles.attitude_deg() or (NAN, NAN, NAN)
        assert (round(roll, 3), round(pitch, 3), round(yaw, 3)) == (3.0, -4.0, 40.0)
        assert vehicles.yaw_deg is not None and math.isclose(vehicles.yaw_deg, 40.0, abs_tol=1e-3)
        # a yaw-locked target 70 deg from North, pitch -20 from the horizon (stabilised: whatever the
        # vehicle's pitch, issue 35.5): body yaw 70 - 40
        autopilot.send(set_attitude(EARTH, 0.0, -20.0, 70.0))
        await eventually(
            lambda: abs(s.gimbal.yaw_deg - 30) < 0.1 and abs(s.gimbal.earth()[1] + 20) < 0.1, 30, "yaw 30, pitch -20"
        )
        # the vehicle turns to 100 deg: the same earth-frame target is -30 deg in the body frame
        autopilot.send(autopilot_state(0.0, 0.0, 100.0))
        await eventually(lambda: vehicles.yaw_deg is not None and abs(vehicles.yaw_deg - 100) < 1e-3, 5)
        autopilot.send(set_attitude(EARTH, 0.0, -20.0, 70.0))
        await eventually(lambda: abs(s.gimbal.yaw_deg + 30) < 0.1, 30, "body yaw 70 - 100 = -30")

        # ATTITUDE is second choice: the preferred message wins while both are fresh
        def both_heard() -> bool:
            autopilot.send(ml.MAVLink_attitude_message(0, 0.0, 0.0, math.radians(10), 0, 0, 0))
            autopilot.send(autopilot_state(0.0, 0.0, 100.0))
            # both: the pair's second datagram may still be on its way when the first was handled
            # (the last AUTOPILOT_STATE was then seconds old, and stale: seen once beside a busy CI)
            heard = vehicles._attitude
            return "ATTITUDE" in heard and heard["AUTOPILOT_STATE_FOR_GIMBAL_DEVICE"][1] >= heard["ATTITUDE"][1]

        await eventually(both_heard, 30, "ATTITUDE and AUTOPILOT_STATE heard together")
        assert vehicles.yaw_deg is not None and abs(vehicles.yaw_deg - 100) < 1e-3
    finally:
        autopilot.close()


async def test_pitch_goes_without_a_heading_and_the_missing_heading_is_logged_once(
    rig_factory: Any, caplog: Any
) -> None:
    r = await rig_factory("C12", role="device")
    s = r.sim
    autopilot = await Peer(sysid=1, compid=1).connect(r.bridge.addresses[0][1])
    caplog.set_level(logging.WARNING, logger="topgimbal.mavlink")
    try:
        s.gimbal.angle("yaw", 12.0)
        await eventually(lambda: abs(s.gimbal.yaw_deg - 12) < 0.05, 10)
        for pitch in (-10.0, -25.0, -35.0):  # a stream with no heading anywhere on the network
            for _ in range(5):
                autopilot.send(set_attitude(EARTH, 0.0, pitch, 70.0))
            await eventually(lambda p=pitch: abs(s.gimbal.pitch_deg - p) < 0.1, 10, f"pitch {pitch}")  # type: ignore[misc]
        assert abs(s.gimbal.yaw_deg - 12) < 0.05, "the yaw is left alone, not taken as a body-frame yaw"
        assert r.bridge.pointer.yaw_dropped >= 3
        lines = [rec for rec in caplog.records if "needs the vehicle's heading" in rec.getMessage()]
        assert len(lines) == 1, [rec.getMessage() for rec in lines]
        assert r.bridge.pointer.stream_errors == 0
        # a command (acked) is refused whole rather than half done
        gcs = r.peer
        ack = await gcs.ack(GIMBAL, ml.MAV_CMD_DO_GIMBAL_MANAGER_PITCHYAW, -5, 70, NAN, NAN,
                            ml.GIMBAL_MANAGER_FLAGS_YAW_LOCK | ml.GIMBAL_MANAGER_FLAGS_YAW_IN_EARTH_FRAME)  # fmt: skip
        assert ack.result in (ml.MAV_RESULT_TEMPORARILY_REJECTED, ml.MAV_RESULT_UNSUPPORTED)
        assert abs(s.gimbal.pitch_deg + 35) < 0.1
        # the heading comes: the yaw goes too
        autopilot.send(autopilot_state(0.0, 0.0, 50.0))
        await eventually(lambda: r.bridge.vehicles.yaw_deg is not None, 5)
        autopilot.send(set_attitude(EARTH, 0.0, -35.0, 70.0))
        await eventually(lambda: abs(s.gimbal.yaw_deg - 20) < 0.1, 10, "body yaw 70 - 50 = 20")
    finally:
        autopilot.close()
