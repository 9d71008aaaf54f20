"""The simulated world's one pose (issue 41.2): the vehicle's attitude and position as the host
tells them, and the camera's axis in the earth frame. The renderer (video/snapshot.py), the truth
file (truth.py), the laser and target solution (handlers/ranging.py) and the camera's tracker
(tracker.py, through the same `GimbalPhysics.earth()`) all read it, so the picture, the truth, the
range and what a bridge computes from the camera's reports describe one world.

The vehicle's heading has two ways in: a vehicle attitude (TOPOTEK UAV, SkyDroid FAI) and a
heading alone (TOPOTEK AZI and GPS, which ArduPilot and the bridge send a SIP). Either sets the
one vehicle yaw the gimbal physics holds its frames in; the newest wins (both are the host's word
for the same heading). Before, AZI reached only the laser: at heading 30 the picture looked 30
degrees off the laser and CAMERA_FOV_STATUS, and a yaw lock did not counter a turn. Pure.
"""

from __future__ import annotations

from dataclasses import dataclass

from ..geo.earth import wrap360
from .physics import GimbalPhysics, wrap180
from .state import HostFeed


@dataclass(frozen=True)
class WorldPose:
    """One moment of the simulated world: degrees in the API convention, earth frame."""

    vehicle_yaw_deg: float
    vehicle_pitch_deg: float
    vehicle_roll_deg: float
    yaw_deg: float  # the camera's axis: bearing, right-positive from north
    pitch_deg: float  # up-positive from the horizon
    roll_deg: float
    lat_deg: float | None = None
    lon_deg: float | None = None
    alt_m: float | None = None

    @property
    def vehicle(self) -> tuple[float, float, float]:
        return self.vehicle_yaw_deg, self.vehicle_pitch_deg, self.vehicle_roll_deg


def pose_of(gimbal: GimbalPhysics, position: HostFeed) -> WorldPose:
    """The world now (call after the physics was brought up to now)."""
    v = gimbal.vehicle
    yaw, pitch, roll = gimbal.earth()
    return WorldPose(
        wrap180(v.yaw), v.pitch, v.roll, yaw, pitch, roll, position.lat_deg, position.lon_deg, position.alt_m
    )


def heading_fed(gimbal: GimbalPhysics, position: HostFeed, heading_deg: float) -> None:
    """The host's heading alone (AZI, GPS): the vehicle's yaw in the world, and what the laser's
    target solution counts from (`position.azimuth_deg`, 0..360 as the frames carry it)."""
    position.azimuth_deg = wrap360(heading_deg)
    gimbal.vehicle.yaw = wrap180(heading_deg)
