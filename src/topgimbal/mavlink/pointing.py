"""Gimbal set-points from MAVLink to the camera, shared by the device and manager roles.

Commands (MAV_CMD_DO_GIMBAL_MANAGER_PITCHYAW) await the camera's confirmation for their ack.
Streamed set-points (GIMBAL_DEVICE_SET_ATTITUDE, GIMBAL_MANAGER_SET_ATTITUDE / SET_PITCHYAW,
sent at 10-50 Hz by autopilots and ground stations) cannot be acked: the latest one wins, one
request to the camera at a time, an unchanged set-point is re-sent only as a keep-alive; nothing
queues up behind a slow camera.

"Unchanged" is judged on what goes to the camera, not on what the autopilot sent: an earth-frame
yaw that stays the same while the vehicle turns is a new body-frame angle at every heading, and is
sent at the rate the heading arrives (paced by the camera link, one request at a time).

While the vehicle turns (faster than FOLLOW_MIN_DEG_S), an earth-frame yaw is held with the
camera's rate commands instead: the vehicle's yaw rate fed forward (the camera counter-turns at the
speed the vehicle turns) plus FOLLOW_GAIN_PER_S times the error the camera reports, plus its
integral (FOLLOW_INTEGRAL_PER_S2, bounded): a fed-forward rate a little off would otherwise leave
the camera behind by what it is off / FOLLOW_GAIN_PER_S. Angle commands
alone lag a turning vehicle by a command period and, on models whose angle commands carry a slow
slew speed (TOPOTEK: 9.9 deg/s at most), cannot keep up at all. A bearing that moves on its own
(an ROI passed or orbited: successive set-points turn) is fed forward too, at the rate estimated
from the set-points of the last BEARING_WINDOW_S; without it the loop trailed such a bearing by its
rate / FOLLOW_GAIN_PER_S (2 deg at 6 deg/s). A rate command keeps the camera
turning between set-points, so it is bounded: when set-points stop for FOLLOW_HOLD_S, the last
angle is sent (the camera stops where the target is) rather than letting it turn on."""

from __future__ import annotations

import asyncio
import contextlib
import logging
import math
from collections import deque
from dataclasses import dataclass

from ..autopilot.vehicle import Vehicles
from ..clock import monotonic
from ..errors import TopGimbalError
from ..geo.earth import wrap180
from ..logthrottle import ThrottledLog
from ..timeouts import stop_tasks, within
from .camera_link import CameraLink
from .commands import rejected, unsupported

log = logging.getLogger("topgimbal.mavlink")

ANGLE_DEADBAND_DEG = 0.05
RATE_DEADBAND_DEG_S = 0.05
ANGLE_REFRESH_S = 1.0
RATE_REFRESH_S = 0.5  # some firmware stops a rate command after a silence
FOLLOW_MIN_DEG_S = 1.0  # the vehicle turns: hold an earth-frame yaw with rate commands
FOLLOW_GAIN_PER_S = 3.0  # deg/s of correction per degree of error (a 0.33 s time constant)
# ... plus the error's integral: a fed-forward rate that is a little off (ArduPilot SITL's
# angular_velocity_z read 6.78 deg/s in a 6.0 deg/s turn; a SITL clock 1 % slow is 1 % off too)
# left the camera rate_error / FOLLOW_GAIN_PER_S off for good (0.24 deg under ArduPilot). The
# integral settles in about 2.6 s (s^2 + 3 s + 1); it is bounded, grown only on small errors and
# not while the command is at the motors' limit, and starts from zero each time following by rate
# starts. (Critical damping, 2.25, amplified the 10 Hz ripple of a camera holding lock itself:
# tests/mavlink/test_orbit.py's p95 went from 0.02 to 0.36 deg.)
FOLLOW_INTEGRAL_PER_S2 = 1.0  # deg/s of correction per degree-second of error
FOLLOW_INTEGRAL_MAX_DEG_S = 1.5  # a quarter of a 6 deg/s turn: more is not a rate slightly off
FOLLOW_INTEGRAL_BAND_DEG = 0.5  # grown only on errors this small: a catch-up or a ripple is the P term's
FOLLOW_INTEGRAL_MAX_DT_S = 0.2  # a longer gap between two set-points is not integrated over
FOLLOW_HOLD_S = 0.3  # no set-point for this long while following by rate: stop on the last angle
ATTITUDE_FRESH_S = 0.3  # the camera's attitude must be this recent to close the loop on it
BEARING_WINDOW_S = 0.5  # the set-points' own turning rate is measured over this long
BEARING_SPAN_MIN_S = 0.15  # ... and only once they span this long (one jittery pair is no rate)


@dataclass(frozen=True)
class Setpoint:
    """Angles (body frame unless earth_yaw) or rates, degrees; None = leave that axis alone.
    neutral: go to the neutral position (the camera's centre command), whatever else is given."""

    yaw_deg: float | None = None
    pitch_deg: float | None = None
    roll_deg: float | None = None
    yaw_rate_deg_s: float | None = None
    pitch_rate_deg_s: float | None = None
    roll_rate_deg_s: float | None = None
    earth_yaw: bool = False
    lock: bool | None = None  # True: yaw lock, False: follow, None: no change
    neutral: bool = False

    @property
    def is_rate(self) -> bool:
        return not self.neutral and self.yaw_deg is None and self.pitch_deg is None and self.roll_deg is None


class Pointer:
    def __init__(self, cam: CameraLink, vehicles: Vehicles) -> None:
        self.cam = cam
        self.vehicles = vehicles
        self.profile = cam.profile
        self.mode: str | None = None  # "lock" / "follow" as last confirmed by the camera
        self._latest: Setpoint | None = None
        self._wake = asyncio.Event()
        self._task: asyncio.Task[None] | None = None
        self._last_sent: tuple[Setpoint, float] | None = None
        self._last_body_yaw: float | None = None  # the body-frame yaw last sent for an earth-frame set-point
        self._latest_t = 0.0
        self.following_by_rate = False  # the last thing sent was a rate command holding an earth yaw
        self.rate_follow_sent = 0
        self.stream_errors = 0
        self._error_log = ThrottledLog(log, 5.0)  # a set-point stream is 50 Hz: one line per 5 s
        self.yaw_dropped = 0  # streamed earth-frame yaws left out for want of a heading
        self._bearings: deque[tuple[float, float]] = deque()  # (arrival, unwrapped earth yaw) of set-points
        self.follow_integral_deg_s = 0.0  # the yaw rate the integral adds while following by rate
        self._integral_t: float | None = None  # when it was last grown (None: not following)
        self._no_heading_logged = False

    def start(self) -> None:
        self._task = asyncio.ensure_future(self._worker())

    async def close(self) -> None:
        if self._task is not None:  # bounded: a worker that swallows a cancellation is given up on
            await stop_tasks([self._task], "gimbal pointer")

    # -- commands (awaited, acked with the camera's answer) -------------------------------------

    async def apply(self, sp: Setpoint, *, clamp: bool = False, partial: bool = False) -> None:
        """Send one set-point and return once the camera confirmed it (raises otherwise).
        `partial` (streams): an earth-frame yaw that cannot be converted (no heading heard) is
        left out and the other axes still go; a command (not partial) is refused whole instead."""
        if sp.neutral:
            if not self.profile.has_neutral:
                raise unsupported("the gimbal has no neutral position command")
            await self.cam.call(lambda c: c.center())
            self._last_sent = (sp, monotonic())
            return
        if sp.lock is not None and (self.profile.has_lock and self.profile.has_follow):
            want = "lock" if sp.lock else "follow"
            # Cameras power up following the vehicle: an unknown mode counts as follow, so plain
            # angle commands (no YAW_LOCK flag) send no mode frame at all.
            if want != (self.mode or "follow"):
                await self.cam.call(lambda c: c.set_mode(want))
                self.mode = want
        if sp.is_rate:
            yr, pr, rr = (self._rate(v, clamp) for v in (sp.yaw_rate_deg_s, sp.pitch_rate_deg_s, sp.roll_rate_deg_s))
            if not self.profile.rate_axes:
                raise rejected(f"the {self.profile.model.name} takes no rate commands")
            await self.cam.call(lambda c: c.rates(yr, pr, rr if "roll" in self.profile.rate_axes else 0.0))
        else:
            yaw, frame = self._body_yaw(sp, partial)
            yaw = self._angle("yaw", yaw, clamp)
            body_yaw = yaw
            pitch = self._angle("pitch", sp.pitch_deg, clamp)
            roll = (
                sp.roll_deg if self.profile.has_roll and sp.roll_deg is not None and abs(sp.roll_deg) > 0.05 else None
            )
            roll = self._angle("roll", roll, clamp)
            if yaw is None and pitch is None and roll is None:
                return
            await self.cam.call(lambda c: c.set_angles(yaw, pitch, roll, frame=frame))
            self._last_body_yaw = body_yaw if frame == "body" else None
        self._last_sent = (sp, monotonic())

    def _body_yaw(self, sp: Setpoint, partial: bool = False) -> tuple[float | None, str]:
        """The yaw to send and its frame. Earth-frame yaw (from North) becomes vehicle-frame yaw
        by subtracting the vehicle's heading: MAVLink's vehicle frame is the earth frame turned
        to the heading, so this is exact whatever the vehicle's roll and pitch. Pitch and roll
        need nothing: the flags autopilots send (ROLL_LOCK, PITCH_LOCK) mean relative to the
        horizon, which is what these stabilised gimbals hold."""
        if sp.yaw_deg is None or not sp.earth_yaw:
            return sp.yaw_deg, "body"
        vehicle_yaw = self.vehicles.yaw_deg
        if vehicle_yaw is not None:
            self._no_heading_logged = False  # the next outage is logged again
            return wrap180(sp.yaw_deg - vehicle_yaw), "body"
        if self.profile.earth_frame:
            return wrap180(sp.yaw_deg), "earth"
        text = (
            "yaw in the earth frame needs the vehicle's heading (AUTOPILOT_STATE_FOR_GIMBAL_DEVICE, "
            "ATTITUDE or GLOBAL_POSITION_INT); none heard"
        )
        if not partial:
            raise rejected(text)
        if not self._no_heading_logged:
            self._no_heading_logged = True  # once per outage, not per set-point (50 Hz)
            log.warning("%s: streamed set-points move pitch and roll only until one comes", text)
        self.yaw_dropped += 1
        return None, "body"

    def _angle(self, axis: str, value: float | None, clamp: bool) -> float | None:
        if value is None or math.isnan(value):
            return None
        if not clamp:
            return value
        lo, hi = getattr(self.profile.model, f"{axis}_range_deg")
        return max(lo, min(hi, value))

    def _rate(self, value: float | None, clamp: bool) -> float:
        if value is None or math.isnan(value):
            return 0.0
        top = self.profile.model.max_rate_deg_s
        return max(-top, min(top, value)) if clamp else value

    # -- streams (latest wins) ----------------------------------------------------------------

    def stream(self, sp: Setpoint) -> None:
        self._latest = sp
        self._latest_t = monotonic()
        self._note_bearing(sp, self._latest_t)
        self._wake.set()

    def _note_bearing(self, sp: Setpoint, t: float) -> None:
        b = self._bearings
        if not sp.earth_yaw or sp.yaw_deg is None or math.isnan(sp.yaw_deg) or (b and t - b[-1][0] > BEARING_WINDOW_S):
            b.clear()  # a body-frame set-point, or a pause: the bearing's motion starts afresh
            if not sp.earth_yaw or sp.yaw_deg is None or math.isnan(sp.yaw_deg):
                return
        yaw = sp.yaw_deg if not b else b[-1][1] + wrap180(sp.yaw_deg - b[-1][1])  # unwrapped across North
        b.append((t, yaw))
        while b and t - b[0][0] > BEARING_WINDOW_S:
            b.popleft()

    def bearing_rate_deg_s(self) -> float:
        """How fast the streamed earth-frame yaw turns on its own (deg/s, right-positive): the
        slope across the last BEARING_WINDOW_S of set-points; 0 when they span too short a time or
        the last one is older than the window."""
        b = self._bearings
        if len(b) < 2 or monotonic() - b[-1][0] > BEARING_WINDOW_S:
            return 0.0
        span_s = b[-1][0] - b[0][0]
        return (b[-1][1] - b[0][1]) / span_s if span_s >= BEARING_SPAN_MIN_S else 0.0

    def _follow_rates(self, sp: Setpoint) -> Setpoint | None:
        """The rate set-point that holds `sp`'s earth-frame yaw on a turning vehicle, or None
        where angle commands are the way (the vehicle is not turning, the model takes no yaw rate
        commands, or the camera's attitude is not streaming to close the loop on)."""
        if not sp.earth_yaw or sp.yaw_deg is None or "yaw" not in self.profile.rate_axes:
            return None
        rate = self.vehicles.yaw_rate_deg_s
        heading = self.vehicles.yaw_deg
        att = self.cam.attitude
        bearing_rate = self.bearing_rate_deg_s()
        if heading is None or att is None or monotonic() - att.t > ATTITUDE_FRESH_S:
            return None
        if abs(rate) < FOLLOW_MIN_DEG_S and abs(bearing_rate) < FOLLOW_MIN_DEG_S:
            return None
        # the bearing now: the last set-point carried forward at the rate the set-points turn
        since_s = min(max(0.0, monotonic() - self._latest_t), FOLLOW_HOLD_S)
        body = self._angle("yaw", wrap180(sp.yaw_deg + bearing_rate * since_s - heading), True)
        assert body is not None
        # where the camera is now: its last report carried forward at the rate it was turning
        age_s = min(max(0.0, monotonic() - att.t), ATTITUDE_FRESH_S)
        camera_yaw = att.yaw_deg + (att.yaw_rate_deg_s * age_s if math.isfinite(att.yaw_rate_deg_s) else 0.0)
        error = wrap180(body - camera_yaw)
        yaw_rate = bearing_rate - rate + FOLLOW_GAIN_PER_S * error + self._grow_integral(error, bearing_rate - rate)
        pitch_rate = 0.0
        pitch = self._angle("pitch", sp.pitch_deg, True)
        if pitch is not None and "pitch" in self.profile.rate_axes:
            pitch_rate = FOLLOW_GAIN_PER_S * (pitch - att.pitch_deg)
        return Setpoint(yaw_rate_deg_s=yaw_rate, pitch_rate_deg_s=pitch_rate, lock=sp.lock)

    def _grow_integral(self, error_deg: float, fed_forward_deg_s: float) -> float:
        """The integral term (deg/s) with `error_deg` added over the time since the last call;
        not grown while the command would be past the motors' limit (it would only wind up)."""
        now = monotonic()
        dt = 0.0 if self._integral_t is None else min(max(0.0, now - self._integral_t), FOLLOW_INTEGRAL_MAX_DT_S)
        self._integral_t = now
        top = self.profile.model.max_rate_deg_s
        grown = self.follow_integral_deg_s + FOLLOW_INTEGRAL_PER_S2 * error_deg * dt
        grown = max(-FOLLOW_INTEGRAL_MAX_DEG_S, min(FOLLOW_INTEGRAL_MAX_DEG_S, grown))
        if (
            abs(error_deg) < FOLLOW_INTEGRAL_BAND_DEG
            and abs(fed_forward_deg_s + FOLLOW_GAIN_PER_S * error_deg + grown) < top
        ):
            self.follow_integral_deg_s = grown
        return self.follow_integral_deg_s

    def cancel_stream(self) -> None:
        self._latest = None
        self._bearings.clear()

    def _is_repeat(self, sp: Setpoint, now: float) -> bool:
        if self._last_sent is None:
            return False
        last, t = self._last_sent
        if (last.lock != sp.lock and sp.lock is not None) or last.earth_yaw != sp.earth_yaw:
            return False
        if last.neutral != sp.neutral:
            return False
        refresh = RATE_REFRESH_S if sp.is_rate else ANGLE_REFRESH_S
        if now - t >= refresh:
            return False
        band = RATE_DEADBAND_DEG_S if sp.is_rate else ANGLE_DEADBAND_DEG
        pairs = zip(
            (sp.yaw_deg, sp.pitch_deg, sp.roll_deg, sp.yaw_rate_deg_s, sp.pitch_rate_deg_s, sp.roll_rate_deg_s),
            (
                last.yaw_deg,
                last.pitch_deg,
                last.roll_deg,
                last.yaw_rate_deg_s,
                last.pitch_rate_deg_s,
                last.roll_rate_deg_s,
            ),
            strict=True,
        )
        for a, b in pairs:
            if (a is None) != (b is None):
                return False
            if a is not None and b is not None and not (math.isnan(a) and math.isnan(b)) and abs(a - b) > band:
                return False
        if sp.earth_yaw and sp.yaw_deg is not None:
            # the same earth bearing is a new body angle once the vehicle has turned
            heading = self.vehicles.yaw_deg
            if heading is not None and self._last_body_yaw is not None:
                body = self._angle("yaw", wrap180(sp.yaw_deg - heading), True)
                if body is not None and abs(wrap180(body - self._last_body_yaw)) > band:
                    return False
            elif (heading is None) != (self._last_body_yaw is None):
                return False
        return True

    async def _worker(self) -> None:
        while True:
            if self.following_by_rate:
                with contextlib.suppress(asyncio.TimeoutError):
                    await within(self._wake.wait(), FOLLOW_HOLD_S)
            else:
                await self._wake.wait()
            self._wake.clear()
            sp = self._latest
            if sp is None:
                continue
            # the stream stopped: never leave the camera turning on a rate
            stopped = monotonic() - self._latest_t >= FOLLOW_HOLD_S
            rates = None if stopped else self._follow_rates(sp)
            if rates is None:
                self.follow_integral_deg_s, self._integral_t = 0.0, None  # angles again: it starts afresh
            send = sp if rates is None else rates
            if rates is None and self.following_by_rate:
                self._last_sent = None  # the angle goes now, whatever was sent before
            if self._is_repeat(send, monotonic()):
                continue
            try:
                await self.apply(send, clamp=True, partial=True)
                self.following_by_rate = rates is not None
                self.rate_follow_sent += rates is not None
            except (TopGimbalError, OSError) as exc:
                self.stream_errors += 1
                if self._error_log.allow("stream") is not None:
                    log.warning("streamed gimbal set-point not applied: %s", exc)
