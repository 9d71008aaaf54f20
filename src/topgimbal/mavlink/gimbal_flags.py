"""What GIMBAL_DEVICE_FLAGS / GIMBAL_MANAGER_FLAGS say about a set-point's yaw: the one place
that reads them, for the device role (GIMBAL_DEVICE_SET_ATTITUDE) and the manager role
(MAV_CMD_DO_GIMBAL_MANAGER_PITCHYAW, GIMBAL_MANAGER_SET_ATTITUDE / SET_PITCHYAW) alike.

MAVLink's common.xml: YAW_LOCK (16) "lock yaw angle to absolute angle relative to North ... if this
flag is set, the yaw angle ... [is] relative to North (earth frame), else ... relative to the
vehicle heading". YAW_IN_VEHICLE_FRAME (32) and YAW_IN_EARTH_FRAME (64) say the frame outright and
override what YAW_LOCK implies. The manager flags are "based on" the device flags, with the same
values. QGroundControl's and MAVSDK's yaw lock send 16 alone: an earth bearing."""

from __future__ import annotations

from typing import Literal

# GIMBAL_DEVICE_FLAGS (= GIMBAL_MANAGER_FLAGS in the low bits)
F_RETRACT, F_NEUTRAL, F_ROLL_LOCK, F_PITCH_LOCK, F_YAW_LOCK = 1, 2, 4, 8, 16
F_YAW_IN_VEHICLE_FRAME, F_YAW_IN_EARTH_FRAME = 32, 64

YawFrame = Literal["earth", "vehicle"]


def yaw_frame(flags: int) -> YawFrame:
    """The frame a set-point's yaw angle and yaw rate are in. Both explicit frame flags at once
    contradict each other; the earth frame wins (what a yaw lock asks for is the safer reading:
    the camera holds a bearing instead of swinging with the vehicle)."""
    if flags & F_YAW_IN_EARTH_FRAME:
        return "earth"
    if flags & F_YAW_IN_VEHICLE_FRAME:
        return "vehicle"
    return "earth" if flags & F_YAW_LOCK else "vehicle"


def yaw_lock(flags: int) -> bool:
    """Whether the camera should hold its yaw in space (its lock mode) rather than follow the
    vehicle: YAW_LOCK asks for it; the frame flags only say how the angle is expressed."""
    return bool(flags & F_YAW_LOCK)
