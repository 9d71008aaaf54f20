"""What the camera looks at, for MAVLink: its field of view and where its axis meets the ground
(CAMERA_FOV_STATUS), its earth-frame orientation (for captured images), and the rangefinder's
distance (DISTANCE_SENSOR, on request or as a stream)."""

from __future__ import annotations

import asyncio
import logging
import math
from typing import TYPE_CHECKING, Any, NamedTuple

from ..autopilot.vehicle import VehicleFix, Vehicles
from ..geo import CORNERS, Attitude, Geodetic, Pointing, Terrain, View
from ..geo import Fix as GeoFix
from ..geo import locate as geo_locate
from ..geo.earth import wrap360
from ..geo.optics import hfov_at, vfov_for
from ..geo.quaternion import from_euler_deg
from ..geo.st0601 import sensor_relative_deg
from ..links.mav import mavlink
from ..outputs.sighting import Sighting
from .camera_link import AttitudeSample, CameraLink
from .commands import Command, rejected
from .node import Component

if TYPE_CHECKING:
    from ..links.mav import MAVLinkMessage

log = logging.getLogger("topgimbal.mavlink")
INT32_MAX = 2**31 - 1


class Pose(NamedTuple):
    """What placing the picture on the ground needs, all heard lately."""

    fix: VehicleFix  # the vehicle's
    attitude: AttitudeSample  # the gimbal's: pitch earth-frame (stabilised), yaw relative to the vehicle
    vehicle_yaw_deg: float


class CameraView:
    def __init__(self, comp: Component, cam: CameraLink, vehicles: Vehicles, *, lens: str, range_hz: float) -> None:
        self.comp = comp
        self.cam = cam
        self.profile = cam.profile
        self.vehicles = vehicles
        self.lens = lens
        self.range_hz = range_hz
        self.last_range_m: float | None = None
        self.terrain: Terrain | None = None  # mavlink --terrain: the DEM the image centre lands on

    def earth_quaternion(self) -> tuple[float, float, float, float]:
        att = self.cam.attitude
        if att is None:
            return (float("nan"),) * 4
        yaw = att.yaw_deg + (self.vehicles.yaw_deg or 0.0)
        return from_euler_deg(att.roll_deg, att.pitch_deg, yaw)

    async def fov_status(self, cmd: Command) -> list[Any]:
        return [self.fov_message()]

    def fov_message(self) -> MAVLinkMessage:
        nan = float("nan")
        fix = self.vehicles.fix()
        vyaw = self.vehicles.yaw_deg
        lat_c = lon_c = lat_i = lon_i = INT32_MAX
        alt_c = alt_i = INT32_MAX
        if fix is not None:
            lat_c, lon_c = int(fix.position.lat_deg * 1e7), int(fix.position.lon_deg * 1e7)
            alt_c = int(fix.position.alt_m * 1000)
            hit = self.locate()
            if hit is not None:
                lat_i, lon_i, alt_i = round(hit.lat_deg * 1e7), round(hit.lon_deg * 1e7), round(hit.alt_m * 1000)
        hfov, vfov = self.fov_deg()
        q = self.earth_quaternion() if vyaw is not None else (nan, nan, nan, nan)
        return mavlink().MAVLink_camera_fov_status_message(
            self.comp.node.time_boot_ms(), lat_c, lon_c, alt_c, lat_i, lon_i, alt_i, list(q), hfov, vfov, 0
        )

    def pose(self) -> Pose | None:
        """The vehicle's fresh fix and heading and the camera's attitude; None without any of them."""
        fix, att, vyaw = self.vehicles.fix(), self.cam.attitude, self.vehicles.yaw_deg
        if fix is None or att is None or vyaw is None:
            return None
        return Pose(fix, att, vyaw)

    def locate(self, x: float = 0.0, y: float = 0.0) -> GeoFix | None:
        """Where the picture point (x, y) (-1..1 from left to right, top to bottom; (0, 0) the
        centre) lands: on the --terrain DEM when there is one, else flat ground at the home
        altitude; None without a fresh vehicle fix and heading, the camera's attitude, or a hit.
        The gimbal's pitch is earth-frame (stabilised), its yaw relative to the vehicle's heading."""
        pose = self.pose()
        if pose is None:
            return None
        fix, att, vyaw = pose
        hfov, vfov = self.fov_deg()
        if math.isnan(hfov):
            hfov, vfov = 60.0, 34.0  # no stream for this lens: only the centre is meaningful
        view = earth_view(fix, att, vyaw, hfov, vfov)
        return geo_locate(view, terrain=self.terrain, ground_alt_m=fix.home_alt_m, x=x, y=y)

    def sighting(self, video_url: str | None = None) -> Sighting | None:
        """What Cursor-on-Target says now (cot.py): None without a fix, heading or attitude, and
        for a fix at 0, 0 (what an autopilot sends before its first GPS fix: unknown, not a place)."""
        pose = self.pose()
        if pose is None or (pose.fix.position.lat_deg == 0 and pose.fix.position.lon_deg == 0):
            return None
        fix, att, vyaw = pose
        hfov, vfov = self.fov_deg()
        corners = [self.locate(x, y) for x, y in CORNERS] if not math.isnan(hfov) else []
        p = fix.position
        return Sighting(
            p.lat_deg, p.lon_deg, p.alt_m, att.yaw_deg + vyaw, att.pitch_deg, att.roll_deg,
            hfov, vfov, self.locate(), corners, video_url,
        )  # fmt: skip

    def klv_values(self) -> dict[int, float | None] | None:
        """MISB ST 0601 values now (klv.py's tags): None without a vehicle fix (st0601_values)."""
        fix = self.vehicles.fix()
        if fix is None:
            return None
        hfov, vfov = self.fov_deg()
        placed = not (fix.position.lat_deg == 0.0 and fix.position.lon_deg == 0.0)
        target = self.locate() if placed else None
        return st0601_values(fix, self.cam.attitude, self.vehicles.attitude_deg(), self.vehicles.yaw_deg, hfov, vfov,
                             target)  # fmt: skip

    def zoom_x(self) -> float:
        """This lens's magnification as the camera last reported it (1 until it has)."""
        client = self.cam.client
        if client is None:
            return 1.0
        state = client.state
        if self.lens == "thermal":
            z = state.extra.get("zoom.thermal_digital_x")
            value = z.value if z is not None else 1.0
        else:
            value = state.zoom.value if state.zoom is not None else 1.0
        return float(value) if isinstance(value, (int, float)) and value >= 1 else 1.0

    def fov_deg(self) -> tuple[float, float]:
        """(horizontal, vertical) field of view now: the profile's at 1x through the pinhole
        lens model at the current zoom; NaN when the model lists no stream for this lens."""
        lens = self.profile.lens(self.lens)
        if lens is None:
            return float("nan"), float("nan")
        hfov = hfov_at(lens.hfov_deg, self.zoom_x())
        return hfov, vfov_for(hfov, *lens.size)

    async def distance_now(self, cmd: Command) -> list[Any]:
        d = await self.cam.call(lambda c: c.range())
        if d is None:
            raise rejected("the rangefinder reported no distance (no target in range)")
        return [self.distance_message(d)]

    def distance_message(self, d: float) -> MAVLinkMessage:
        lo, hi = self.profile.rangefinder or (0.0, 0.0)
        att = self.cam.attitude
        q = from_euler_deg(att.roll_deg, att.pitch_deg, att.yaw_deg) if att else (0.0, 0.0, 0.0, 0.0)
        self.last_range_m = d
        return mavlink().MAVLink_distance_sensor_message(
            self.comp.node.time_boot_ms(), int(lo * 100), min(65535, int(hi * 100)), min(65535, int(d * 100)),
            0, 0, 100 if att else 25, 255, 0.0, 0.0, list(q), 0)  # fmt: skip

    async def range_loop(self) -> None:
        while True:
            await asyncio.sleep(1.0 / self.range_hz)
            if not self.cam.answering:
                continue
            try:
                d = await self.cam.call(lambda c: c.range())
            except Exception as exc:
                log.debug("range measurement failed: %s", exc)
                continue
            if d is not None and not math.isnan(d):
                self.comp.send(self.distance_message(d))


def earth_view(fix: VehicleFix, att: AttitudeSample, vehicle_yaw_deg: float, hfov_deg: float, vfov_deg: float) -> View:
    """The camera's view for topgimbal.geo: its yaw is relative to the vehicle's heading, its
    pitch and roll to the horizon (a stabilised gimbal), so the earth-frame pointing is exact
    whatever the vehicle's roll and pitch."""
    p = fix.position
    return View(
        Geodetic(p.lat_deg, p.lon_deg, p.alt_m),
        Attitude(yaw_deg=vehicle_yaw_deg),
        Pointing(att.yaw_deg + vehicle_yaw_deg, att.pitch_deg, att.roll_deg, earth_frame=True),
        hfov_deg,
        vfov_deg,
    )


def st0601_values(
    fix: VehicleFix,
    att: AttitudeSample | None,
    vehicle_attitude_deg: tuple[float, float, float] | None,
    heading_deg: float | None,
    hfov_deg: float,
    vfov_deg: float,
    target: GeoFix | None,
) -> dict[int, float | None]:
    """MISB ST 0601 values (klv.py's tags). Unknown values are None (left out, as ST 0601 says),
    never 0: an autopilot without a GPS fix sends GLOBAL_POSITION_INT at 0, 0, which is no
    position. The sensor angles (18-20) are relative to the platform's axes after its heading,
    pitch and roll (geo/st0601.py); `target` is where the optical axis meets the ground."""
    p = fix.position
    placed = not (p.lat_deg == 0.0 and p.lon_deg == 0.0)
    target = target if placed else None
    vatt = vehicle_attitude_deg
    relative: tuple[float | None, float | None, float | None] = (None, None, None)
    if att is not None:
        # The gimbal's yaw is relative to the heading, its pitch and roll to the horizon. With no
        # heading heard, azimuth is still the body yaw; with no attitude, the platform is level.
        vroll, vpitch = (vatt[0], vatt[1]) if vatt is not None else (0.0, 0.0)
        h = heading_deg if heading_deg is not None else 0.0
        relative = sensor_relative_deg(
            Attitude(vroll, vpitch, h), Attitude(att.roll_deg, att.pitch_deg, att.yaw_deg + h)
        )
    return {
        5: wrap360(heading_deg) if heading_deg is not None else None,
        6: vatt[1] if vatt is not None else None,
        7: vatt[0] if vatt is not None else None,
        13: p.lat_deg if placed else None,
        14: p.lon_deg if placed else None,
        15: p.alt_m if placed else None,
        16: hfov_deg,
        17: vfov_deg,
        18: relative[0],
        19: relative[1],
        20: relative[2],
        21: target.range_m if target is not None else None,
        23: target.lat_deg if target is not None else None,
        24: target.lon_deg if target is not None else None,
        25: target.alt_m if target is not None else None,
    }
