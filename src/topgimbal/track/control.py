"""The companion loop's control law: pure, time passed in.

The picture is late: by the time a frame is decoded and the tracker has found the target in it,
the gimbal has moved on. So a detection is turned into an *earth-frame direction* with the gimbal's
attitude at the frame's capture time (`AttitudeHistory.at`), not its attitude now; the target's
angular velocity is estimated from successive directions; and the error the controller acts on is
between the target predicted to now and the gimbal's attitude now. A PI controller on that angle
error plus the target's velocity as feed-forward gives the gimbal's rates:

    rate = v_target + kp * error + ki * integral(error)     (each axis, clamped to max_rate)

With the latency compensated, the remaining lag is the controller's own, which the feed-forward
and the integral take out (a P-only loop on raw pixels lags a target moving at v by v / kp plus
the video latency times v, and overshoots when its gain is raised to shorten that).
"""

from __future__ import annotations

import math
from collections import deque
from dataclasses import dataclass

from ..geo.earth import wrap180  # the one angle wrap; importable from here as before


class AttitudeHistory:
    """The gimbal's recent attitudes (monotonic time, yaw, pitch), to look up the attitude at a
    past frame's capture time. Bounded: the newest MAX_SAMPLES are kept."""

    MAX_SAMPLES = 512

    def __init__(self) -> None:
        self._samples: deque[tuple[float, float, float]] = deque(maxlen=self.MAX_SAMPLES)

    def add(self, t: float, yaw_deg: float, pitch_deg: float) -> None:
        if self._samples and t <= self._samples[-1][0]:
            return  # out of order or repeated: keep time increasing
        self._samples.append((t, yaw_deg, pitch_deg))

    def __len__(self) -> int:
        return len(self._samples)

    def latest(self) -> tuple[float, float, float] | None:
        return self._samples[-1] if self._samples else None

    def rate(self, t: float, span_s: float = 0.1) -> tuple[float, float]:
        """The gimbal's (yaw, pitch) rate in deg/s over `span_s` around t, within the samples
        there are (0, 0 without a quarter of that): how fast a target the picture holds still is
        moving."""
        s = self._samples
        if len(s) < 2:
            return 0.0, 0.0
        t1 = min(t + span_s / 2, s[-1][0])
        t0 = max(t1 - span_s, s[0][0])
        a, b = self.at(t0), self.at(t1)
        if a is None or b is None or t1 - t0 < span_s / 4:
            return 0.0, 0.0
        return wrap180(b[0] - a[0]) / (t1 - t0), (b[1] - a[1]) / (t1 - t0)

    def at(self, t: float) -> tuple[float, float] | None:
        """(yaw, pitch) at time t: interpolated between samples, extrapolated from the last two
        beyond the newest (at most 0.2 s), the oldest before the first."""
        s = self._samples
        if not s:
            return None
        if t <= s[0][0]:
            return s[0][1], s[0][2]
        if t >= s[-1][0]:
            if len(s) < 2:
                return s[-1][1], s[-1][2]
            (t0, y0, p0), (t1, y1, p1) = s[-2], s[-1]
            k = min(t - t1, 0.2) / max(1e-6, t1 - t0)
            return y1 + wrap180(y1 - y0) * k, p1 + (p1 - p0) * k
        lo, hi = 0, len(s) - 1
        while hi - lo > 1:  # binary search: the deque is indexable
            mid = (lo + hi) // 2
            if s[mid][0] <= t:
                lo = mid
            else:
                hi = mid
        (t0, y0, p0), (t1, y1, p1) = s[lo], s[hi]
        k = (t - t0) / max(1e-9, t1 - t0)
        return y0 + wrap180(y1 - y0) * k, p0 + (p1 - p0) * k


@dataclass(frozen=True)
class Gains:
    kp_per_s: float = 3.0  # proportional: deg/s per degree of error
    ki_per_s2: float = 1.5  # integral: deg/s per degree-second
    feed_forward: float = 1.0  # share of the target's estimated velocity added to the rate
    integral_limit_deg_s: float = 2.0  # the integral term's largest contribution (anti wind-up)
    integrate_within_deg: float = 0.5  # the integral only counts errors this small (no wind-up in a pull-in)
    max_rate_deg_s: float = 30.0
    velocity_tau_s: float = 0.25  # time constant of the target velocity estimate


class AngleController:
    """PI on the angle between the predicted target and the gimbal, with velocity feed-forward."""

    def __init__(self, gains: Gains | None = None) -> None:
        self.g = gains or Gains()
        self.target: tuple[float, float, float] | None = None  # (t, bearing, elevation) last seen
        self.velocity = (0.0, 0.0)  # deg/s (bearing, elevation)
        self.integral = (0.0, 0.0)  # deg/s contributed by the integral term
        self._last_cmd_t: float | None = None

    def reset(self) -> None:
        self.target, self.velocity, self.integral, self._last_cmd_t = None, (0.0, 0.0), (0.0, 0.0), None

    def assume_velocity(self, bearing_deg_s: float, elevation_deg_s: float) -> None:
        """Start the target's velocity estimate here rather than at rest: a loop that starts on a
        gimbal already panning with its target (issue 41.5) would otherwise first command the pan
        away and lose the target while the estimate catches up."""
        self.velocity = (bearing_deg_s, elevation_deg_s)

    def observe(self, t: float, bearing_deg: float, elevation_deg: float) -> None:
        """The target seen at capture time t in this earth-frame direction."""
        if self.target is not None and t > self.target[0]:
            t0, b0, e0 = self.target
            dt = t - t0
            vb, ve = wrap180(bearing_deg - b0) / dt, (elevation_deg - e0) / dt
            k = 1.0 - math.exp(-dt / self.g.velocity_tau_s)
            self.velocity = (
                self.velocity[0] + k * (vb - self.velocity[0]),
                self.velocity[1] + k * (ve - self.velocity[1]),
            )
        if self.target is None or t >= self.target[0]:
            self.target = (t, bearing_deg, elevation_deg)

    def predict(self, t: float) -> tuple[float, float] | None:
        """Where the target is expected at time t (constant velocity from the last sighting)."""
        if self.target is None:
            return None
        t0, b, e = self.target
        dt = max(0.0, t - t0)
        return wrap180(b + self.velocity[0] * dt), e + self.velocity[1] * dt

    def command(self, t: float, yaw_deg: float, pitch_deg: float) -> tuple[float, float]:
        """Yaw and pitch rates (deg/s) at time t for a gimbal at (yaw, pitch) now."""
        aim = self.predict(t)
        if aim is None:
            return 0.0, 0.0
        g = self.g
        dt = 0.0 if self._last_cmd_t is None else min(0.2, max(0.0, t - self._last_cmd_t))
        self._last_cmd_t = t
        err = (wrap180(aim[0] - yaw_deg), aim[1] - pitch_deg)
        lim = g.integral_limit_deg_s
        self.integral = tuple(  # type: ignore[assignment]
            max(-lim, min(lim, i + (g.ki_per_s2 * e * dt if abs(e) < g.integrate_within_deg else 0.0)))
            for i, e in zip(self.integral, err, strict=True)
        )
        out = []
        for v, e, i in zip(self.velocity, err, self.integral, strict=True):
            r = g.feed_forward * v + g.kp_per_s * e + i
            out.append(max(-g.max_rate_deg_s, min(g.max_rate_deg_s, r)))
        return out[0], out[1]


@dataclass(frozen=True)
class PixelPGains:
    """ArduPilot's companion example, for comparison: P only, on the target's raw pixel offset in
    the newest frame, no latency or velocity term. The gain is said as deg/s per degree of offset
    (the pixel gain times the pixels per degree), so the two loops compare at the same stiffness."""

    kp_per_s: float = 3.0
    max_rate_deg_s: float = 30.0


def pixel_p_rates(offset_deg: tuple[float, float], gains: PixelPGains) -> tuple[float, float]:
    lim = gains.max_rate_deg_s
    return (
        max(-lim, min(lim, gains.kp_per_s * offset_deg[0])),
        max(-lim, min(lim, gains.kp_per_s * offset_deg[1])),
    )
