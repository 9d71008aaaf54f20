"""Gimbal protocol v2, gimbal device role: the camera as a MAVLink gimbal device that an
autopilot's gimbal manager drives (ArduPilot MNT1_TYPE=6, PX4's gimbal manager).

Sends GIMBAL_DEVICE_ATTITUDE_STATUS (quaternion, angular velocity, lock flags, failure flags)
as camera attitude frames arrive, decimated to the configured rate, and on its own at that rate
while the camera is silent (then with COMMS_ERROR). Answers GIMBAL_DEVICE_INFORMATION with the
model's limits and capability flags. Takes GIMBAL_DEVICE_SET_ATTITUDE in angle and rate form."""

from __future__ import annotations

import asyncio
import math
from collections.abc import Mapping, Sequence
from typing import TYPE_CHECKING, Any

from ..clock import monotonic
from ..geo.quaternion import from_euler_deg, is_valid, to_euler_deg
from ..links.mav import mavlink, msg_id
from ..timeouts import stop_tasks
from .camera_link import AttitudeSample, CameraLink
from .commands import Command
from .gimbal_flags import (
    F_NEUTRAL,
    F_PITCH_LOCK,
    F_RETRACT,
    F_ROLL_LOCK,
    F_YAW_IN_VEHICLE_FRAME,
    F_YAW_LOCK,
    yaw_frame,
    yaw_lock,
)
from .pointing import Pointer, Setpoint
from .services import Services

if TYPE_CHECKING:
    from ..links.mav import MAVLinkMessage

MSG_ATTITUDE_STATUS = msg_id("GIMBAL_DEVICE_ATTITUDE_STATUS")
MSG_DEVICE_INFORMATION = msg_id("GIMBAL_DEVICE_INFORMATION")
LIMIT_MARGIN_DEG = 0.5

# GIMBAL_DEVICE_ERROR_FLAGS
E_AT_ROLL_LIMIT, E_AT_PITCH_LIMIT, E_AT_YAW_LIMIT, E_COMMS_ERROR, E_NO_MANAGER = 1, 2, 4, 128, 512


def device_cap_flags(pointer: Pointer) -> int:
    """GIMBAL_DEVICE_CAP_FLAGS true to the model (the manager's flags share the low 16 bits)."""
    p = pointer.profile
    yaw = p.has_yaw
    # neutral 2, roll axis + horizon follow 4|8, pitch axis + follow 32|64, yaw axis 256, yaw follow
    # 512, yaw lock 1024, earth frame 4096
    return flag_bits({2: p.has_neutral, 4 | 8: p.has_roll, 32 | 64: p.has_pitch, 256: yaw,
                      512: yaw and p.has_follow, 1024: yaw and p.has_lock, 4096: p.earth_frame})  # fmt: skip


def flag_bits(bits: Mapping[int, object]) -> int:
    """A MAVLink bit field: the OR of every bit (or group of bits) whose condition holds."""
    out = 0
    for bit, on in bits.items():
        if on:
            out |= bit
    return out


def firmware_code(version: str | None) -> int:
    """MAVLink's uint32 version (major | minor << 8 | patch << 16 | dev << 24) from text like
    `1.2.3`, `V1.2.0` or `010502` (two digits each)."""
    if not version:
        return 0
    text = version.strip().lstrip("vV")
    parts = [int(x) for x in text.replace("-", ".").split(".") if x.isdigit()]
    if len(parts) == 1 and len(text) == 3 and text.isdigit():
        parts = [int(c) for c in text]
    elif len(parts) == 1 and len(text) in (4, 6, 8) and text.isdigit():
        parts = [int(text[i : i + 2]) for i in range(0, len(text), 2)]
    parts = [min(255, p) for p in parts[:4]] + [0] * (4 - min(4, len(parts)))
    return parts[0] | parts[1] << 8 | parts[2] << 16 | parts[3] << 24


class GimbalDevice:
    MESSAGES: tuple[str, ...] = ("GIMBAL_DEVICE_SET_ATTITUDE",)  # what on_message reads (node.on)

    def __init__(
        self,
        services: Services,
        cam: CameraLink,
        pointer: Pointer,
        *,
        attitude_hz: float,
        gimbal_device_id: int = 0,
        accept_set_attitude: bool = True,
        identity: dict[str, Any] | None = None,
    ) -> None:
        self.services = services
        self.comp = services.comp
        self.cam = cam
        self.pointer = pointer
        self.profile = cam.profile
        self.gimbal_device_id = gimbal_device_id
        self.accept_set_attitude = accept_set_attitude
        self.identity = identity if identity is not None else {}
        top = cam.stream_rate_hz
        self.stream = services.add_stream(MSG_ATTITUDE_STATUS, None, min(attitude_hz, top), top)
        services.provide(MSG_DEVICE_INFORMATION, self._information)
        services.provide(MSG_ATTITUDE_STATUS, self._status_now)
        self._last_sent = 0.0
        self.status_sent = 0
        self.set_attitude_received = 0
        self._task: asyncio.Task[None] | None = None
        cam.on_attitude(self._on_attitude)
        cam.on_health(self._on_health)

    def start(self) -> None:
        self._task = asyncio.ensure_future(self._fallback())

    async def close(self) -> None:
        if self._task is not None:  # bounded, as every close
            await stop_tasks([self._task], "gimbal device")

    # -- attitude status -----------------------------------------------------------------------

    def status_message(self, att: AttitudeSample | None) -> MAVLinkMessage:
        flags = F_ROLL_LOCK | F_PITCH_LOCK | F_YAW_IN_VEHICLE_FRAME
        if self.pointer.mode == "lock":
            flags |= F_YAW_LOCK
        failure = 0
        if not self.cam.answering:
            failure |= E_COMMS_ERROR
        nan = float("nan")
        if att is None:
            q: tuple[float, ...] = (nan, nan, nan, nan)
            wx = wy = wz = nan
        else:
            q = from_euler_deg(att.roll_deg, att.pitch_deg, att.yaw_deg)
            wx, wy, wz = (math.radians(v) for v in (att.roll_rate_deg_s, att.pitch_rate_deg_s, att.yaw_rate_deg_s))
            m = self.profile.model
            for axis, value, bit in (("roll", att.roll_deg, E_AT_ROLL_LIMIT), ("pitch", att.pitch_deg, E_AT_PITCH_LIMIT),
                                     ("yaw", att.yaw_deg, E_AT_YAW_LIMIT)):  # fmt: skip
                lo, hi = getattr(m, f"{axis}_range_deg")
                if value <= lo + LIMIT_MARGIN_DEG or value >= hi - LIMIT_MARGIN_DEG:
                    failure |= bit
        return mavlink().MAVLink_gimbal_device_attitude_status_message(
            0, 0, self.services.comp.node.time_boot_ms(), flags, list(q), wx, wy, wz, failure,
            nan, nan, self.gimbal_device_id)  # fmt: skip

    def _send_status(self) -> None:
        self.comp.send(self.status_message(self.cam.attitude))
        self._last_sent = monotonic()
        self.status_sent += 1

    def _on_attitude(self, att: AttitudeSample) -> None:
        period = self.stream.period_s
        if period <= 0:
            return
        if monotonic() - self._last_sent >= period * 0.9:  # 10 % slack for clock jitter
            self._send_status()

    def _on_health(self, answering: bool) -> None:
        if self.stream.period_s > 0:
            self._send_status()  # the failure flags change now, not at the next sample

    async def _fallback(self) -> None:
        """While no attitude arrives, keep the status flowing at the configured rate (the
        autopilot must see the failure flag, not silence)."""
        while True:
            period = self.stream.period_s
            await asyncio.sleep(period if period > 0 else 1.0)
            if period > 0 and monotonic() - self._last_sent > period * 1.5:
                self._send_status()

    async def _status_now(self, cmd: Command) -> list[Any]:
        return [self.status_message(self.cam.attitude)]

    # -- information ---------------------------------------------------------------------------

    async def _information(self, cmd: Command) -> list[Any]:
        return [self.information_message()]

    def information_message(self) -> MAVLinkMessage:
        m = self.profile.model
        rad = math.radians
        return mavlink().MAVLink_gimbal_device_information_message(
            self.comp.node.time_boot_ms(),
            _text(self.profile.vendor, 32),
            _text(self.identity.get("model_name") or m.name, 32),
            _text(m.title, 32),
            firmware_code(self.identity.get("version")),
            0,
            0,
            device_cap_flags(self.pointer),
            0,
            rad(m.roll_range_deg[0]), rad(m.roll_range_deg[1]),
            rad(m.pitch_range_deg[0]), rad(m.pitch_range_deg[1]),
            rad(m.yaw_range_deg[0]), rad(m.yaw_range_deg[1]),
            self.gimbal_device_id,
        )  # fmt: skip

    # -- set-points from the autopilot ---------------------------------------------------------

    def on_message(self, msg: MAVLinkMessage) -> None:
        if msg.get_type() != "GIMBAL_DEVICE_SET_ATTITUDE" or not self.accept_set_attitude:
            return
        if msg.target_system not in (0, self.comp.sysid) or msg.target_component not in (0, self.comp.compid):
            return
        self.set_attitude_received += 1
        sp = setpoint_from(msg.flags, msg.q, (msg.angular_velocity_x, msg.angular_velocity_y, msg.angular_velocity_z))
        if sp is not None and (self.profile.has_neutral or not sp.neutral):
            # Latest wins, NEUTRAL too: a flood of them is one centre request, not one task each.
            self.pointer.stream(sp)


def setpoint_from(flags: int, q: Sequence[float], rates_rad_s: tuple[float, float, float]) -> Setpoint | None:
    """A set-point from the angle (quaternion) or rate form of a SET_ATTITUDE message; None
    when it carries neither. RETRACT (which these gimbals cannot do) and NEUTRAL take precedence
    over everything else, as the MAVLink flags say. A NaN (MAVLink's "ignore") or infinite rate
    is no rate: garbage must not turn into the model's top speed by clamping."""
    if flags & F_RETRACT:
        return None
    if flags & F_NEUTRAL:
        return Setpoint(neutral=True)
    lock: bool | None = yaw_lock(flags)
    earth = yaw_frame(flags) == "earth"
    if is_valid(list(q)):
        e = to_euler_deg(list(q))
        return Setpoint(e.yaw_deg, e.pitch_deg, e.roll_deg, earth_yaw=earth, lock=lock)
    r = [math.degrees(v) if math.isfinite(v) else None for v in rates_rad_s]
    if all(v is None for v in r):
        return None
    return Setpoint(roll_rate_deg_s=r[0], pitch_rate_deg_s=r[1], yaw_rate_deg_s=r[2], lock=lock)


def _text(s: str, n: int) -> bytes:
    return s.encode("utf-8", "replace")[:n]
