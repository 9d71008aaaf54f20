"""Pointing by closing the loop over rate commands, for gimbals that ignore angle commands. Pure:
the controller decides rates from attitude samples and times; `api_motion.point()` feeds it.

The C11's firmware echoes GAM / GAY / GAP and does nothing (its profile says so: `ignored`), and
some firmware ignores angle commands without saying (`point()` notices that nothing moves). Then
each axis is driven by its rate command: the rate is proportional to the error, capped by the
gimbal's rate limit and by what it can brake from in the distance left (so it does not overshoot),
and never below the smallest rate the command carries (so it does not stall short of the target).
Once both axes are within the tolerance the client stops the gimbal and checks a fresh sample.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass, field

from .state import GimbalAttitude

GAIN_PER_S = 4.0  # deg/s of rate per degree of error: ~0.25 s to close the last degrees
BRAKE_SHARE = 0.5  # of the gimbal's acceleration, kept for braking (latency, quantised rates)
RESEND_S = 0.5  # an unchanged rate is sent again this often (some firmware stops a silent rate)


@dataclass(frozen=True)
class AxisLimits:
    max_rate_deg_s: float  # what the rate command and the gimbal allow
    step_deg_s: float  # the smallest non-zero rate the command carries
    accel_deg_s2: float  # the gimbal's acceleration (profile)


def axis_rate(error_deg: float, limits: AxisLimits, tolerance_deg: float) -> float:
    """The rate (deg/s, API sign) that closes `error_deg` on one axis; 0 within the tolerance."""
    distance = abs(error_deg)
    if distance <= tolerance_deg:
        return 0.0
    brake = math.sqrt(2.0 * limits.accel_deg_s2 * BRAKE_SHARE * distance)
    rate = min(limits.max_rate_deg_s, GAIN_PER_S * distance, brake)
    step = limits.step_deg_s
    rate = max(step, math.floor(rate / step + 1e-9) * step)  # quantise down: never faster than asked
    return math.copysign(rate, error_deg)


@dataclass
class RateLoop:
    """One pointing: targets per axis, what each axis allows, the tolerance. `step(sample, now)`
    returns the rates to send now ({axis: deg/s}; empty: nothing new to send) or None once the
    target is reached (the caller then stops the gimbal and confirms with a fresh sample)."""

    targets: Mapping[str, float]
    limits: Mapping[str, AxisLimits]
    tolerance_deg: float
    sent: dict[str, float] = field(default_factory=dict)
    sent_at: float = -math.inf
    samples: int = 0
    worst_overshoot_deg: float = 0.0
    _sign0: dict[str, float] = field(default_factory=dict)

    def errors(self, att: GimbalAttitude) -> dict[str, float]:
        return errors(self.targets, att)

    def reached(self, att: GimbalAttitude) -> bool:
        return within(self.targets, att, self.tolerance_deg)

    def step(self, att: GimbalAttitude, now: float) -> dict[str, float] | None:
        self.samples += 1
        errors = self.errors(att)
        for axis, e in errors.items():
            first = self._sign0.setdefault(axis, math.copysign(1.0, e) if e else 0.0)
            if first and e * first < 0:  # past the target: how far
                self.worst_overshoot_deg = max(self.worst_overshoot_deg, abs(e))
        if all(abs(e) <= self.tolerance_deg for e in errors.values()):
            return None
        rates = {axis: axis_rate(e, self.limits[axis], self.tolerance_deg) for axis, e in errors.items()}
        if rates == self.sent and now - self.sent_at < RESEND_S:
            return {}
        self.sent, self.sent_at = dict(rates), now
        return rates


def errors(targets: Mapping[str, float], att: GimbalAttitude) -> dict[str, float]:
    """{axis: target - attitude} (degrees)."""
    got = {"yaw": att.yaw_deg, "pitch": att.pitch_deg, "roll": att.roll_deg}
    return {axis: target - got[axis] for axis, target in targets.items()}


def within(targets: Mapping[str, float], att: GimbalAttitude, tolerance_deg: float) -> bool:
    return all(abs(e) <= tolerance_deg for e in errors(targets, att).values())


def stalled(start: GimbalAttitude, now: GimbalAttitude, targets: Mapping[str, float], tolerance_deg: float) -> bool:
    """Whether an angle command was apparently ignored: some axis still outside the tolerance has
    moved less than a fifth of a degree towards its target."""
    before, after = errors(targets, start), errors(targets, now)
    for axis in targets:
        e0, e1 = before[axis], after[axis]
        if abs(e1) > tolerance_deg and abs(e0) - abs(e1) < min(0.2, abs(e0) / 2):
            return True
    return False
