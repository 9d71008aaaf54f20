"""Gimbal protocol v2, gimbal manager role: direct control from a ground station.

GIMBAL_MANAGER_INFORMATION / GIMBAL_MANAGER_STATUS, MAV_CMD_DO_GIMBAL_MANAGER_PITCHYAW (acked
when the camera confirmed), MAV_CMD_DO_GIMBAL_MANAGER_CONFIGURE (who is in control),
GIMBAL_MANAGER_SET_ATTITUDE / SET_PITCHYAW (streams, latest wins) and the ROI commands, which
point at a place while the vehicle's position and heading are heard on the network."""

from __future__ import annotations

import asyncio
import contextlib
import logging
import math
from typing import TYPE_CHECKING, Any

from ..autopilot.vehicle import Vehicles
from ..geo.aim import Geodetic, look_at
from ..links.mav import mav_id, mavlink, msg_id
from .camera_link import CameraLink
from .commands import Command, Outcome, denied, rejected, unsupported
from .gimbal_device import device_cap_flags, setpoint_from
from .gimbal_flags import F_NEUTRAL, F_RETRACT, F_YAW_LOCK, yaw_frame, yaw_lock
from .pointing import Pointer, Setpoint
from .services import Services

if TYPE_CHECKING:
    from ..links.mav import MAVLinkMessage

log = logging.getLogger("topgimbal.mavlink")

MSG_MANAGER_INFORMATION = msg_id("GIMBAL_MANAGER_INFORMATION")
MSG_MANAGER_STATUS = msg_id("GIMBAL_MANAGER_STATUS")
CMD_PITCHYAW = mav_id("MAV_CMD_DO_GIMBAL_MANAGER_PITCHYAW")
CMD_CONFIGURE = mav_id("MAV_CMD_DO_GIMBAL_MANAGER_CONFIGURE")
CMD_ROI_LOCATION = mav_id("MAV_CMD_DO_SET_ROI_LOCATION")
CMD_ROI_WPNEXT_OFFSET = mav_id("MAV_CMD_DO_SET_ROI_WPNEXT_OFFSET")
CMD_ROI_NONE = mav_id("MAV_CMD_DO_SET_ROI_NONE")
CMD_ROI_SYSID = mav_id("MAV_CMD_DO_SET_ROI_SYSID")
CMD_ROI = mav_id("MAV_CMD_DO_SET_ROI")
CAN_POINT_LOCATION_GLOBAL = 131072
# How often a held target (an ROI, or a commanded earth bearing) is streamed to the pointer: well
# inside pointing.FOLLOW_HOLD_S, so a turning vehicle is followed by rate, not stopped on an angle.
ROI_PERIOD_S = 0.1


class GimbalManager:
    MESSAGES: tuple[str, ...] = (
        "GIMBAL_MANAGER_SET_ATTITUDE",
        "GIMBAL_MANAGER_SET_PITCHYAW",
    )  # what on_message reads (node.on)

    def __init__(
        self, services: Services, cam: CameraLink, pointer: Pointer, vehicles: Vehicles, *, gimbal_device_id: int
    ) -> None:
        self.services = services
        self.comp = services.comp
        self.cam = cam
        self.pointer = pointer
        self.vehicles = vehicles
        self.gimbal_device_id = gimbal_device_id
        self.primary: tuple[int, int] = (0, 0)
        self.secondary: tuple[int, int] = (0, 0)
        self.roi: Geodetic | int | None = None  # a place, or a system id to follow
        # An earth-frame yaw commanded once (DO_GIMBAL_MANAGER_PITCHYAW with YAW_LOCK: what QGC's and
        # MAVSDK's yaw lock send), held while the vehicle turns until another set-point replaces it.
        self.held: Setpoint | None = None
        self._roi_task: asyncio.Task[None] | None = None
        self._stopping: asyncio.Future[None] | None = None
        services.provide(MSG_MANAGER_INFORMATION, self._information)
        services.provide(MSG_MANAGER_STATUS, self._status_now)
        services.add_stream(MSG_MANAGER_STATUS, self.status_message, 5.0, 20.0)
        d = services.dispatcher
        d.register(self.comp, CMD_PITCHYAW, self._pitchyaw)
        d.register(self.comp, CMD_CONFIGURE, self._configure)
        for c in (CMD_ROI_LOCATION, CMD_ROI_NONE, CMD_ROI_SYSID, CMD_ROI):
            d.register(self.comp, c, self._roi_command)

    async def close(self) -> None:
        await self._stop_roi()

    # -- information and status ----------------------------------------------------------------

    def information_message(self) -> MAVLinkMessage:
        m = self.cam.profile.model
        rad = math.radians
        return mavlink().MAVLink_gimbal_manager_information_message(
            self.comp.node.time_boot_ms(), device_cap_flags(self.pointer) | CAN_POINT_LOCATION_GLOBAL,
            self.gimbal_device_id, rad(m.roll_range_deg[0]), rad(m.roll_range_deg[1]),
            rad(m.pitch_range_deg[0]), rad(m.pitch_range_deg[1]), rad(m.yaw_range_deg[0]), rad(m.yaw_range_deg[1]),
        )  # fmt: skip

    async def _information(self, cmd: Command) -> list[Any]:
        return [self.information_message()]

    def status_message(self) -> MAVLinkMessage:
        flags = 4 | 8 | 32  # roll and pitch lock, yaw in the vehicle frame
        if self.pointer.mode == "lock":
            flags |= F_YAW_LOCK
        return mavlink().MAVLink_gimbal_manager_status_message(
            self.comp.node.time_boot_ms(), flags, self.gimbal_device_id, *self.primary, *self.secondary)  # fmt: skip

    async def _status_now(self, cmd: Command) -> list[Any]:
        return [self.status_message()]

    # -- control -------------------------------------------------------------------------------

    def _check_control(self, sysid: int, compid: int) -> None:
        if self.primary == (0, 0):
            return  # nobody took control: everyone may steer
        if (sysid, compid) in (self.primary, self.secondary):
            return
        raise denied(f"{sysid}/{compid} is not in control (primary {self.primary[0]}/{self.primary[1]})")

    def _for_us(self, gimbal_device_id: float) -> bool:
        # NaN: not given (any device); inf or a fraction is no device id, so not ours.
        return math.isnan(gimbal_device_id) or gimbal_device_id in (0, self.gimbal_device_id)

    async def _configure(self, cmd: Command) -> Outcome:
        if not self._for_us(cmd.p(7)):
            raise denied(f"gimbal device {cmd.p(7):g} is not managed here (ours: {self.gimbal_device_id})")
        me = (cmd.src_system, cmd.src_component)
        # Both pairs are checked before either is changed: a bad secondary leaves the primary as it was.
        primary = _control(self.primary, cmd, 1, "primary", me)
        secondary = _control(self.secondary, cmd, 3, "secondary", me)
        self.primary, self.secondary = primary, secondary
        self.comp.send(self.status_message())
        return Outcome()

    # -- pointing ------------------------------------------------------------------------------

    async def _pitchyaw(self, cmd: Command) -> Outcome:
        if not self._for_us(cmd.p(7)):
            raise denied(f"gimbal device {cmd.p(7):g} is not managed here (ours: {self.gimbal_device_id})")
        self._check_control(cmd.src_system, cmd.src_component)
        flags = cmd.whole(5, "gimbal manager flags", 0, 2**32 - 1, default=0)
        if flags & F_RETRACT:
            raise unsupported("the gimbal cannot retract")
        await self._stop_roi()
        self.pointer.cancel_stream()
        if flags & F_NEUTRAL:
            await self.pointer.apply(Setpoint(neutral=True))
            return Outcome()
        lock = yaw_lock(flags)
        earth = yaw_frame(flags) == "earth"
        if cmd.has(1) or cmd.has(2):
            sp = Setpoint(
                yaw_deg=cmd.p(2) if cmd.has(2) else None,
                pitch_deg=cmd.p(1) if cmd.has(1) else None,
                earth_yaw=earth,
                lock=lock,
            )
        elif cmd.has(3) or cmd.has(4):
            sp = Setpoint(
                yaw_rate_deg_s=cmd.p(4) if cmd.has(4) else 0.0,
                pitch_rate_deg_s=cmd.p(3) if cmd.has(3) else 0.0,
                lock=lock,
            )
        else:
            raise denied("neither angles (param1, param2) nor rates (param3, param4) given")
        await self.pointer.apply(sp)
        if sp.earth_yaw and sp.yaw_deg is not None:
            self.held = sp
            self._roi_task = asyncio.ensure_future(self._follow_roi())
        return Outcome()

    def on_message(self, msg: MAVLinkMessage) -> None:
        kind = msg.get_type()
        if kind not in ("GIMBAL_MANAGER_SET_ATTITUDE", "GIMBAL_MANAGER_SET_PITCHYAW"):
            return
        if msg.target_system not in (0, self.comp.sysid) or msg.target_component not in (0, self.comp.compid):
            return
        if not self._for_us(float(msg.gimbal_device_id)):
            return
        if self.primary != (0, 0) and (msg.get_srcSystem(), msg.get_srcComponent()) not in (
            self.primary,
            self.secondary,
        ):
            return  # not in control: ignored, as the protocol says
        if kind == "GIMBAL_MANAGER_SET_ATTITUDE":
            sp = setpoint_from(
                msg.flags, msg.q, (msg.angular_velocity_x, msg.angular_velocity_y, msg.angular_velocity_z)
            )
        else:
            sp = _pitchyaw_setpoint(msg)
        if sp is not None and (self.cam.profile.has_neutral or not sp.neutral):
            self._cancel_roi_soon()
            self.pointer.stream(sp)

    # -- region of interest --------------------------------------------------------------------

    async def _roi_command(self, cmd: Command) -> Outcome:
        self._check_control(cmd.src_system, cmd.src_component)
        c = cmd.command
        if c == CMD_ROI:  # deprecated form: param1 = MAV_ROI mode
            mode = cmd.whole(1, "MAV_ROI mode", 0, 255)
            if mode == 0:
                c = CMD_ROI_NONE
            elif mode == 3:
                c = CMD_ROI_LOCATION
            else:
                raise unsupported(f"MAV_CMD_DO_SET_ROI mode {mode} (supported: 0 none, 3 location)")
        else:
            device_param = 2 if c == CMD_ROI_SYSID else 1  # ROI_SYSID: param1 is the system to follow
            if not self._for_us(cmd.p(device_param)):
                raise denied(
                    f"gimbal device {cmd.p(device_param):g} is not managed here (ours: {self.gimbal_device_id})"
                )
        if c == CMD_ROI_NONE:
            await self._stop_roi()
            return Outcome()
        if c == CMD_ROI_SYSID:
            sysid = cmd.whole(1, "system id", 1, 255)
            if self.vehicles.fix(sysid) is None:
                raise rejected(f"no position heard from system {sysid}")
            target: Geodetic | int = sysid
        else:
            alt = cmd.finite(7, "altitude in metres")
            lat, lon = cmd.lat_deg, cmd.lon_deg
            if not (-90 <= lat <= 90 and -180 <= lon <= 180):  # also refuses NaN and inf
                raise denied(f"location {lat:g}, {lon:g}: expected latitude -90..90 and longitude -180..180 degrees")
            if cmd.frame in (3, 6):  # relative to home
                fix = self.vehicles.fix()
                if fix is None:
                    raise rejected("the vehicle's position is not known yet (no GLOBAL_POSITION_INT)")
                alt += fix.home_alt_m
            target = Geodetic(lat, lon, alt)
        bearing, pitch = self._aim(target)
        await self._stop_roi()
        self.pointer.cancel_stream()
        await self.pointer.apply(Setpoint(yaw_deg=bearing, pitch_deg=pitch, earth_yaw=True), clamp=True)
        self.roi = target
        self._roi_task = asyncio.ensure_future(self._follow_roi())
        return Outcome()

    def _aim(self, target: Geodetic | int) -> tuple[float, float]:
        """Earth-frame (bearing, pitch) in degrees from our vehicle to `target`. The pointer turns
        the bearing into a body angle with the heading when it sends it, and follows the bearing's
        own motion (an ROI passed or orbited) by rate while the vehicle turns."""
        fix = self.vehicles.fix()
        yaw = self.vehicles.yaw_deg
        if fix is None or yaw is None:
            raise rejected("the vehicle's position and heading are not known yet")
        if isinstance(target, int):
            other = self.vehicles.fix(int(target))
            if other is None:
                raise rejected(f"no position heard from system {target}")
            place = other.position
        else:
            place = target
        return look_at(fix.position, 0.0, place)

    async def _follow_roi(self) -> None:
        """Stream the held target (the ROI's bearing now, or the commanded earth bearing) to the
        pointer, which re-aims as the vehicle turns, until a new set-point replaces it."""
        while self.roi is not None or self.held is not None:
            await asyncio.sleep(ROI_PERIOD_S)
            if self.roi is not None:
                try:
                    bearing, pitch = self._aim(self.roi)
                except Exception:
                    continue  # position not heard for a moment: hold the last direction
                self.pointer.stream(Setpoint(yaw_deg=bearing, pitch_deg=pitch, earth_yaw=True))
            elif self.held is not None:
                self.pointer.stream(self.held)

    async def _stop_roi(self) -> None:
        self.roi = None
        self.held = None
        task, self._roi_task = self._roi_task, None
        if task is not None:
            task.cancel()
            with contextlib.suppress(asyncio.CancelledError, Exception):
                await task

    def _cancel_roi_soon(self) -> None:
        # One stop at a time: a burst of set-points in one datagram is one task, not one each.
        if (self.roi is not None or self.held is not None) and (self._stopping is None or self._stopping.done()):
            self._stopping = asyncio.ensure_future(self._stop_roi())


def _control(current: tuple[int, int], cmd: Command, n: int, which: str, me: tuple[int, int]) -> tuple[int, int]:
    """MAV_CMD_DO_GIMBAL_MANAGER_CONFIGURE's rules for the (system id, component id) in params n,
    n + 1: -1 leave, -2 take for the sender, -3 release if the sender holds it, 0..255 set (0 =
    nobody); anything else is refused."""
    sysid = cmd.whole(n, f"{which} control system id: -1 leave, -2 take, -3 release, or 0..255", -3, 255, default=-1)
    if sysid == -1:
        return current
    if sysid == -2:
        return me
    if sysid == -3:
        return (0, 0) if current == me else current
    return (sysid, cmd.whole(n + 1, f"{which} control component id", 0, 255, default=0))


def _pitchyaw_setpoint(msg: MAVLinkMessage) -> Setpoint | None:
    """GIMBAL_MANAGER_SET_PITCHYAW: NaN = ignore that value (angles win over rates), RETRACT and
    NEUTRAL take precedence; an infinite value counts as not given."""
    if msg.flags & F_RETRACT:
        return None
    if msg.flags & F_NEUTRAL:
        return Setpoint(neutral=True)
    pitch, yaw, pitch_rate, yaw_rate = (
        v if math.isfinite(v) else math.nan for v in (msg.pitch, msg.yaw, msg.pitch_rate, msg.yaw_rate)
    )
    deg = math.degrees
    lock = yaw_lock(msg.flags)
    earth = yaw_frame(msg.flags) == "earth"
    if not (math.isnan(pitch) and math.isnan(yaw)):
        return Setpoint(
            yaw_deg=None if math.isnan(yaw) else deg(yaw),
            pitch_deg=None if math.isnan(pitch) else deg(pitch),
            earth_yaw=earth,
            lock=lock,
        )
    if math.isnan(pitch_rate) and math.isnan(yaw_rate):
        return None
    return Setpoint(
        yaw_rate_deg_s=0.0 if math.isnan(yaw_rate) else deg(yaw_rate),
        pitch_rate_deg_s=0.0 if math.isnan(pitch_rate) else deg(pitch_rate),
        lock=lock,
    )
