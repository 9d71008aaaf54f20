"""The yaw frame of a gimbal set-point, as MAVLink's common.xml defines it (issue 41 item 1):
YAW_LOCK alone means an earth bearing (what QGroundControl's and MAVSDK's yaw lock send),
YAW_IN_VEHICLE_FRAME and YAW_IN_EARTH_FRAME say the frame outright. Every combination of the
three, on the device path (GIMBAL_DEVICE_SET_ATTITUDE) and the three manager paths
(MAV_CMD_DO_GIMBAL_MANAGER_PITCHYAW, GIMBAL_MANAGER_SET_PITCHYAW, GIMBAL_MANAGER_SET_ATTITUDE),
measured on the simulated camera's body yaw with the vehicle's heading at 30 deg. Flag values come
from pymavlink's enums, not from the product's constants."""

from __future__ import annotations

import itertools
import math
from typing import Any

import pytest
from pymavlink.dialects.v20 import common as ml

from topgimbal.mavlink.gimbal_device import setpoint_from
from topgimbal.mavlink.gimbal_flags import yaw_frame
from topgimbal.mavlink.gimbal_manager import _pitchyaw_setpoint
from topgimbal.mavlink.quaternion import from_euler_deg

from .conftest import NAN, eventually
from .virtual import MemPeer

pytestmark = pytest.mark.virtual

GIMBAL = 154
HEADING_DEG = 30.0
LOCK, VEHICLE, EARTH = (
    ml.GIMBAL_MANAGER_FLAGS_YAW_LOCK,
    ml.GIMBAL_MANAGER_FLAGS_YAW_IN_VEHICLE_FRAME,
    ml.GIMBAL_MANAGER_FLAGS_YAW_IN_EARTH_FRAME,
)
# The device flags the manager flags are "based on" carry the same values.
assert (LOCK, VEHICLE, EARTH) == (
    ml.GIMBAL_DEVICE_FLAGS_YAW_LOCK,
    ml.GIMBAL_DEVICE_FLAGS_YAW_IN_VEHICLE_FRAME,
    ml.GIMBAL_DEVICE_FLAGS_YAW_IN_EARTH_FRAME,
)


def spec_frame(lock: bool, vehicle: bool, earth: bool) -> str:
    """common.xml read clause by clause: an explicit frame flag says the frame (both at once
    contradict each other: the earth frame, as the product documents); otherwise YAW_LOCK set means
    "relative to North", unset "relative to the vehicle heading"."""
    if earth:
        return "earth"
    if vehicle:
        return "vehicle"
    return "earth" if lock else "vehicle"


COMBOS = [
    pytest.param(
        (LOCK if lk else 0) | (VEHICLE if v else 0) | (EARTH if e else 0),
        spec_frame(lk, v, e),
        id=f"lock{int(lk)}-vehicle{int(v)}-earth{int(e)}",
    )
    for lk, v, e in itertools.product((False, True), repeat=3)
]
STABILISED = ml.GIMBAL_MANAGER_FLAGS_ROLL_LOCK | ml.GIMBAL_MANAGER_FLAGS_PITCH_LOCK


@pytest.mark.parametrize(("flags", "frame"), COMBOS)
def test_yaw_frame_of_every_flag_combination(flags: int, frame: str) -> None:
    assert yaw_frame(flags) == frame
    assert yaw_frame(flags | STABILISED) == frame  # roll and pitch lock say nothing about yaw


class _PitchYaw:
    """A GIMBAL_MANAGER_SET_PITCHYAW as the receiving side sees it."""

    def __init__(self, flags: int, yaw_rad: float) -> None:
        self.flags, self.pitch, self.yaw, self.pitch_rate, self.yaw_rate = flags, -0.3, yaw_rad, NAN, NAN


@pytest.mark.parametrize(("flags", "frame"), COMBOS)
def test_device_and_manager_parsers_agree(flags: int, frame: str) -> None:
    device = setpoint_from(flags, list(from_euler_deg(0, -20, 41)), (NAN, NAN, NAN))
    manager = _pitchyaw_setpoint(_PitchYaw(flags, math.radians(41)))
    assert device is not None and manager is not None
    assert device.earth_yaw == manager.earth_yaw == (frame == "earth")
    assert device.lock == manager.lock == bool(flags & LOCK)


def _device(flags: int, yaw_deg: float) -> Any:
    q = list(from_euler_deg(0.0, -20.0, yaw_deg))
    return ml.MAVLink_gimbal_device_set_attitude_message(1, GIMBAL, flags, q, NAN, NAN, NAN)


def _manager_attitude(flags: int, yaw_deg: float) -> Any:
    q = list(from_euler_deg(0.0, -20.0, yaw_deg))
    return ml.MAVLink_gimbal_manager_set_attitude_message(1, GIMBAL, flags, 0, q, NAN, NAN, NAN)


def _manager_pitchyaw(flags: int, yaw_deg: float) -> Any:
    return ml.MAVLink_gimbal_manager_set_pitchyaw_message(
        1, GIMBAL, flags, 0, math.radians(-20.0), math.radians(yaw_deg), NAN, NAN
    )


PATHS = ["command", "device", "manager_attitude", "manager_pitchyaw"]
STREAMS = {"device": _device, "manager_attitude": _manager_attitude, "manager_pitchyaw": _manager_pitchyaw}


@pytest.mark.parametrize("path", PATHS)
@pytest.mark.parametrize(("flags", "frame"), COMBOS)
async def test_every_path_points_in_the_frame_the_flags_say(vrig_maker: Any, path: str, flags: int, frame: str) -> None:
    vrig = await vrig_maker("C12")
    await eventually(lambda: vrig.bridge.cam.answering, 10, "camera answering")
    autopilot = await MemPeer(sysid=1, compid=1).join(vrig.link)
    vehicles = vrig.bridge.vehicles
    autopilot.send(ml.MAVLink_attitude_message(0, 0.0, 0.0, math.radians(HEADING_DEG), 0, 0, 0))
    await eventually(lambda: vehicles.yaw_deg is not None, 5, "heading heard")
    asked_deg = 41.0  # the example: 41 from North is 11 right of a vehicle heading 30
    want_deg = asked_deg - HEADING_DEG if frame == "earth" else asked_deg
    p, g = vrig.peer, vrig.sim.gimbal
    if path == "command":
        ack = await p.ack(GIMBAL, ml.MAV_CMD_DO_GIMBAL_MANAGER_PITCHYAW, -20, asked_deg, NAN, NAN, flags, 0, 0)
        assert ack.result == ml.MAV_RESULT_ACCEPTED
    else:
        p.send(STREAMS[path](flags, asked_deg))
    await eventually(lambda: abs(g.yaw_deg - want_deg) < 0.05 and abs(g.pitch_deg + 20) < 0.05, 10,
                     f"body yaw {want_deg:g} ({frame} frame), at {g.yaw_deg:.2f}")  # fmt: skip
    assert (g.mode == "lock") == bool(flags & LOCK)
    autopilot.close()
