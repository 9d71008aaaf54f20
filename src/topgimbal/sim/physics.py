"""Gimbal physics: pure, I/O-free, driven by explicit time steps.

Every angle here is in the API convention (yaw right-positive, pitch up-positive, roll
right-positive, degrees) and in the gimbal's *body* frame (what the magnetic encoders read). Wire
signs and units are the dispatcher's business, so the physics is the same for every dialect.

Each axis obeys a position range, a rate limit and an acceleration limit. It is in one of two
modes: *rate* (a commanded speed, e.g. GSY / YPR / PTZ nudges) or *angle* (a commanded target in
the body frame, GA*, or the earth frame, GI*, converted with the vehicle attitude the host sends).
When a rate command ends the axis decelerates and then *holds*: in the earth frame for pitch and
roll (a stabilised gimbal) and for yaw in lock mode, in the body frame for yaw in follow mode.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

from ..geo.earth import wrap180  # the one angle wrap; importable from here as before

AXES = ("yaw", "pitch", "roll")
# Physics integrates in steps no longer than this, so results do not depend on how a test or the
# event loop slices time (a 1 s `advance` equals a hundred 10 ms ones to within float error).
MAX_STEP_S = 0.002


@dataclass(frozen=True)
class AxisLimits:
    lo: float
    hi: float
    max_rate: float
    max_accel: float

    def clamp(self, a: float) -> float:
        return min(self.hi, max(self.lo, a))


@dataclass(slots=True)
class Axis:
    """One motor axis. `frame` says how `target` is read: "body" or "earth"."""

    name: str
    limits: AxisLimits
    pos: float = 0.0
    vel: float = 0.0
    mode: str = "angle"  # "angle" or "rate"
    target: float = 0.0
    frame: str = "body"
    speed: float = 0.0  # angle mode: slew speed cap (deg/s)
    rate_cmd: float = 0.0  # rate mode: commanded speed (deg/s)

    def command_rate(self, rate: float) -> None:
        self.mode = "rate"
        self.rate_cmd = max(-self.limits.max_rate, min(self.limits.max_rate, rate))

    def command_angle(self, target: float, speed: float | None = None, frame: str = "body") -> None:
        self.mode = "angle"
        self.frame = frame
        self.target = target
        cap = self.limits.max_rate if speed is None or speed <= 0 else speed
        self.speed = min(cap, self.limits.max_rate)

    def at_rest(self, vehicle: float) -> bool:
        """Holding still on its target: nothing to integrate (checked on every stream frame, so
        written out rather than through `body_target`)."""
        if self.mode != "angle" or self.vel != 0.0:
            return False
        t = self.target
        if self.frame == "earth":
            t = wrap180(t - vehicle) if self.name == "yaw" else t - vehicle
        lim = self.limits
        return self.pos == (lim.lo if t < lim.lo else lim.hi if t > lim.hi else t)

    def body_target(self, vehicle: float) -> float:
        """The target in the body frame, clamped to the range (never overshoot the stops)."""
        t = self.target
        if self.frame == "earth":
            t = t - vehicle
            if self.name == "yaw":
                t = wrap180(t)
        return self.limits.clamp(t)

    def step(self, dt: float, vehicle: float, hold_frame: str) -> None:
        lim = self.limits
        dv = lim.max_accel * dt
        if self.mode == "rate":
            self.vel += max(-dv, min(dv, self.rate_cmd - self.vel))
            self.pos += self.vel * dt
            if self.pos <= lim.lo or self.pos >= lim.hi:
                self.pos = lim.clamp(self.pos)
                self.vel = 0.0
            if self.rate_cmd == 0.0 and self.vel == 0.0:
                # Stopped: hold here, in the frame this axis stabilises in.
                self.command_angle(self.pos + (vehicle if hold_frame == "earth" else 0.0), None, hold_frame)
            return
        goal = self.body_target(vehicle)
        err = goal - self.pos
        if err == 0.0 and self.vel == 0.0:
            return
        vmax = self.speed if self.speed > 0 else lim.max_rate
        # Trapezoidal profile: the fastest speed from which the axis can still stop at the goal.
        v_des = math.copysign(min(vmax, math.sqrt(2.0 * lim.max_accel * abs(err))), err)
        self.vel += max(-dv, min(dv, v_des - self.vel))
        new = self.pos + self.vel * dt
        if (goal - new) * err <= 0.0 or abs(goal - new) < 1e-6:
            # Would cross the goal this step: arrive exactly (never overshoot).
            self.pos, self.vel = goal, 0.0
        else:
            self.pos = lim.clamp(new)


@dataclass(slots=True)
class Vehicle:
    """The vehicle attitude the host reports (UAV / FAI), API convention, degrees."""

    yaw: float = 0.0
    pitch: float = 0.0
    roll: float = 0.0

    def get(self, axis: str) -> float:
        return float(getattr(self, axis))


@dataclass(slots=True)
class GimbalPhysics:
    """Three axes plus the modes the PTZ codes switch."""

    yaw_axis: Axis
    pitch_axis: Axis
    roll_axis: Axis
    motors_on: bool = True
    mode: str = "follow"  # "follow" or "lock"
    mount: str = "hanging"  # "hanging" or "inverted"
    trims: dict[str, float] = field(default_factory=lambda: {"x": 0.0, "y": 0.0, "z": 0.0})
    vehicle: Vehicle = field(default_factory=Vehicle)
    calibrations: int = 0

    @classmethod
    def for_limits(
        cls,
        yaw: tuple[float, float],
        pitch: tuple[float, float],
        roll: tuple[float, float],
        max_rate: float,
        max_accel: float,
    ) -> GimbalPhysics:
        def mk(name: str, rng: tuple[float, float]) -> Axis:  # pitch and roll start level (stabilised)
            return Axis(
                name, AxisLimits(rng[0], rng[1], max_rate, max_accel), frame="body" if name == "yaw" else "earth"
            )

        return cls(mk("yaw", yaw), mk("pitch", pitch), mk("roll", roll))

    # -- state ---------------------------------------------------------------------------------

    def axis(self, name: str) -> Axis:
        return {"yaw": self.yaw_axis, "pitch": self.pitch_axis, "roll": self.roll_axis}[name]

    @property
    def yaw_deg(self) -> float:
        return self.yaw_axis.pos

    @property
    def pitch_deg(self) -> float:
        return self.pitch_axis.pos

    @property
    def roll_deg(self) -> float:
        return self.roll_axis.pos

    def body(self) -> tuple[float, float, float]:
        """Encoder angles (GAC)."""
        return self.yaw_axis.pos, self.pitch_axis.pos, self.roll_axis.pos

    def horizon(self) -> tuple[float, float, float]:
        """What a stabilised gimbal's own attitude sensor reports: yaw from the vehicle's nose (the
        encoder), pitch and roll from the horizon (SkyDroid GAC, decision in docs/errata.md)."""
        earth = self.earth()
        return self.yaw_axis.pos, earth[1], earth[2]

    def earth(self) -> tuple[float, float, float]:
        """Attitude in the earth frame (GIC / GIA): body plus vehicle, yaw wrapped to ±180."""
        v = self.vehicle
        return (
            wrap180(self.yaw_axis.pos + v.yaw),
            self.pitch_axis.pos + v.pitch,
            self.roll_axis.pos + v.roll,
        )

    def hold_frame(self, axis: str) -> str:
        if axis == "yaw":
            return "earth" if self.mode == "lock" else "body"
        return "earth"

    @property
    def moving(self) -> bool:
        y, p, r = self.yaw_axis, self.pitch_axis, self.roll_axis
        return bool(y.vel or p.vel or r.vel) or "rate" in (y.mode, p.mode, r.mode)

    # -- commands ------------------------------------------------------------------------------

    def rate(self, axis: str, deg_s: float) -> None:
        if self.motors_on:
            self.axis(axis).command_rate(deg_s)

    def angle(self, axis: str, deg: float, speed: float | None = None, frame: str = "body") -> None:
        """Go to `deg` on `axis`. Pitch and roll are stabilised: held from the horizon (the earth
        frame) whatever frame the command names, on every model (issue 35.5: a C12 told "level" sat
        at the vehicle's tilt); yaw goes where `frame` says."""
        if self.motors_on:
            self.axis(axis).command_angle(deg, speed, frame if axis == "yaw" else "earth")

    def stop(self) -> None:
        for name in AXES:
            ax = self.axis(name)
            if ax.mode == "rate":
                ax.command_rate(0.0)  # decelerate, then hold where it stops

    def center(self) -> None:
        for name in AXES:
            self.angle(name, 0.0)

    def set_mode(self, mode: str) -> None:
        self.mode = mode
        yaw = self.yaw_axis
        if yaw.mode == "angle" and yaw.frame != "earth" and mode == "lock":
            # Entering lock: keep the heading we have now in the earth frame.
            yaw.command_angle(yaw.pos + self.vehicle.yaw, yaw.speed, "earth")
        elif yaw.mode == "angle" and mode == "follow" and yaw.frame == "earth":
            yaw.command_angle(yaw.pos, yaw.speed, "body")

    def set_motors(self, on: bool) -> None:
        self.motors_on = on
        if not on:
            for name in AXES:
                a = self.axis(name)
                a.vel = 0.0
                a.command_angle(a.pos, None, "body")

    # -- time ----------------------------------------------------------------------------------

    def advance(self, dt: float) -> None:
        if dt <= 0 or not self.motors_on:
            return
        v = self.vehicle
        if self.yaw_axis.at_rest(v.yaw) and self.pitch_axis.at_rest(v.pitch) and self.roll_axis.at_rest(v.roll):
            return  # at rest on every target: nothing to integrate, however long it has been idle
        axes = [(self.axis(name), v.get(name), self.hold_frame(name)) for name in AXES]
        n = max(1, math.ceil(dt / MAX_STEP_S - 1e-9))
        h = dt / n
        for _ in range(n):
            for ax, veh, hold in axes:
                if not ax.at_rest(veh):
                    ax.step(h, veh, hold)


# The old name, kept for code that imported it: `topgimbal.Gimbal` is the client's blocking facade,
# and one name for two classes misled readers (issue 28). Deprecated: use GimbalPhysics.
Gimbal = GimbalPhysics
