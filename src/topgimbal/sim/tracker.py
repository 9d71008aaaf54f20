"""The camera's own object tracker, as the simulator models it. Pure: no I/O, time passed in.

Once tracking starts on a box (TOPOTEK `LOC`) or a point (SkyDroid `GOT`), the tracker locks on
the target whose picture covers the box's centre region, or, with no target there, on the patch
of scene under the box (a real tracker follows texture: it then holds still). Every step it sees
the target where it truly is (when visible and in the picture), estimates its angular velocity
and drives the gimbal's yaw and pitch rates with velocity feed-forward plus a proportional term
on the angle error, within the model's rate limit (the physics applies the acceleration limit).
When the target is hidden the tracker coasts on its velocity estimate; hidden longer than the
model's `coast_s`, or outside the picture, the target is lost: the gimbal stops and the state
says "lost" (what each dialect reports for it is the handlers' business; docs/errata.md).

Angles are earth-frame degrees in the API convention (bearing right-positive, elevation up).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

from ..protocol import DeviceModel
from .physics import GimbalPhysics, wrap180
from .targets import TargetView

TRACK_STEP_S = 0.02  # the tracker runs once per video frame of a 50 Hz camera
PICTURE_ASPECT = 720 / 1280  # the visible picture the tracker works on (video/lens.py's size)
ASSUMED_HFOV_DEG = 60.0
VELOCITY_ALPHA = 0.3  # low-pass of the per-frame velocity estimate
POINT_BOX = 0.06  # a point request searches a box this wide (fraction of the picture) around it


@dataclass(frozen=True)
class TrackerTraits:
    """What differs between the models' trackers (none of it documented: docs/errata.md)."""

    coast_s: float  # how long a hidden target is predicted before it is declared lost
    gain_per_s: float  # proportional gain on the angle error (1/s)


TRAITS = {"topotek": TrackerTraits(coast_s=1.0, gain_per_s=4.0), "skydroid": TrackerTraits(coast_s=0.6, gain_per_s=3.0)}


def traits_for(model: DeviceModel) -> TrackerTraits:
    return TRAITS.get(model.dialect, TRAITS["topotek"])


def hfov_for(model: DeviceModel, zoom_x: float) -> float:
    """The visible lens's horizontal field of view at a magnification (pinhole)."""
    base = next((v.hfov_deg for v in model.video if v.lens == "visible" and v.hfov_deg), None)
    h = float(base or ASSUMED_HFOV_DEG)
    return math.degrees(2.0 * math.atan(math.tan(math.radians(h) / 2.0) / max(1.0, zoom_x)))


def vfov_for(hfov_deg: float) -> float:
    return math.degrees(2.0 * math.atan(math.tan(math.radians(hfov_deg) / 2.0) * PICTURE_ASPECT))


def project(
    yaw_deg: float, pitch_deg: float, az_deg: float, el_deg: float, hfov_deg: float
) -> tuple[float, float] | None:
    """Picture position (fractions, 0, 0 top left) of an earth direction seen by a camera looking
    along (yaw, pitch), roll 0; None behind it. May lie outside 0..1 (off the picture)."""
    y, p = math.radians(yaw_deg), math.radians(pitch_deg)
    a, e = math.radians(az_deg), math.radians(el_deg)
    d = (math.cos(e) * math.cos(a), math.cos(e) * math.sin(a), math.sin(e))
    fwd = (math.cos(p) * math.cos(y), math.cos(p) * math.sin(y), math.sin(p))
    right = (-math.sin(y), math.cos(y), 0.0)
    up = (-math.sin(p) * math.cos(y), -math.sin(p) * math.sin(y), math.cos(p))
    z = sum(i * j for i, j in zip(d, fwd, strict=True))
    if z <= 1e-6:
        return None
    tx = math.tan(math.radians(hfov_deg) / 2.0)
    ty = tx * PICTURE_ASPECT
    x = sum(i * j for i, j in zip(d, right, strict=True)) / z
    u = sum(i * j for i, j in zip(d, up, strict=True)) / z
    return 0.5 + x / (2.0 * tx), 0.5 - u / (2.0 * ty)


def unproject(yaw_deg: float, pitch_deg: float, fx: float, fy: float, hfov_deg: float) -> tuple[float, float]:
    """Earth direction (bearing, elevation) of a picture position (fractions); roll 0."""
    y, p = math.radians(yaw_deg), math.radians(pitch_deg)
    tx = math.tan(math.radians(hfov_deg) / 2.0)
    a, b = (fx - 0.5) * 2.0 * tx, (0.5 - fy) * 2.0 * tx * PICTURE_ASPECT
    fwd = (math.cos(p) * math.cos(y), math.cos(p) * math.sin(y), math.sin(p))
    right = (-math.sin(y), math.cos(y), 0.0)
    up = (-math.sin(p) * math.cos(y), -math.sin(p) * math.sin(y), math.cos(p))
    ray = [f + a * r + b * u for f, r, u in zip(fwd, right, up, strict=True)]
    n = math.sqrt(sum(c * c for c in ray))
    return wrap180(math.degrees(math.atan2(ray[1], ray[0]))), math.degrees(math.asin(ray[2] / n))


@dataclass
class CameraTracker:
    """One camera's tracker. `state`: stopped, waiting (armed, no box yet), tracking, lost."""

    traits: TrackerTraits
    max_rate_deg_s: float
    state: str = "stopped"
    target: str | None = None  # the locked target's name; None: a patch of scene (holds still)
    az_deg: float = 0.0  # the tracker's estimate of the target's direction
    el_deg: float = 0.0
    vaz_deg_s: float = 0.0
    vel_deg_s: float = 0.0
    size_deg: float = 0.0
    last_seen: float = 0.0
    last_t: float | None = None
    box: tuple[float, float, float, float] | None = None  # centre x, y, width, height (fractions)
    driving: bool = False  # the tracker is commanding the gimbal's rates

    @classmethod
    def for_model(cls, model: DeviceModel) -> CameraTracker:
        return cls(traits_for(model), float(model.max_rate_deg_s))

    def arm(self, gimbal: GimbalPhysics) -> None:
        """Start / ready without a box: wait for one (TOPOTEK TRC 01 / 02)."""
        self._release(gimbal)
        self.state, self.target, self.box = "waiting", None, None

    def stop(self, gimbal: GimbalPhysics) -> None:
        self._release(gimbal)
        self.state, self.target, self.box = "stopped", None, None

    def _release(self, gimbal: GimbalPhysics) -> None:
        if self.driving:
            gimbal.stop()  # decelerate and hold, as after any rate command
            self.driving = False

    def start(
        self,
        t: float,
        gimbal: GimbalPhysics,
        hfov_deg: float,
        box: tuple[float, float, float, float],
        targets: Sequence[TargetView],
    ) -> None:
        """Begin tracking what is in `box` (centre x, y, width, height: fractions of the picture)."""
        yaw, pitch, _ = gimbal.earth()
        cx, cy, w, h = box
        best: tuple[float, TargetView] | None = None
        for tv in targets:
            if not tv.visible:
                continue
            pos = project(yaw, pitch, tv.bearing_deg, tv.elevation_deg, hfov_deg)
            if pos is None:
                continue
            r = tv.size_deg / hfov_deg / 2.0  # its radius as a fraction of the picture's width
            dx, dy = abs(pos[0] - cx), abs(pos[1] - cy) * PICTURE_ASPECT
            if dx <= w / 2 + r and dy <= h / 2 * PICTURE_ASPECT + r:
                d = math.hypot(dx, dy)
                if best is None or d < best[0]:
                    best = (d, tv)
        if best is not None:
            tv = best[1]
            self.target, self.az_deg, self.el_deg, self.size_deg = (
                tv.name,
                tv.bearing_deg,
                tv.elevation_deg,
                tv.size_deg,
            )
        else:
            self.target = None
            self.az_deg, self.el_deg = unproject(yaw, pitch, cx, cy, hfov_deg)
            self.size_deg = max(w, 0.01) * hfov_deg
        self.vaz_deg_s = self.vel_deg_s = 0.0
        self.state, self.last_seen, self.last_t = "tracking", t, t
        self._box(yaw, pitch, hfov_deg)

    def _box(self, yaw: float, pitch: float, hfov_deg: float) -> bool:
        """Place the box on the estimate; False when that is off the picture."""
        pos = project(yaw, pitch, self.az_deg, self.el_deg, hfov_deg)
        if pos is None or not (0.0 <= pos[0] <= 1.0 and 0.0 <= pos[1] <= 1.0):
            return False
        w = self.size_deg / hfov_deg
        self.box = (pos[0], pos[1], w, w / PICTURE_ASPECT)
        return True

    def update(self, t: float, gimbal: GimbalPhysics, hfov_deg: float, targets: Sequence[TargetView]) -> None:
        """One tracker frame at time t: observe, estimate, command the gimbal, or lose it."""
        if self.state != "tracking" or self.last_t is None:
            return
        dt = t - self.last_t
        if dt <= 0:
            return
        self.last_t = t
        yaw, pitch, _ = gimbal.earth()
        seen = None
        if self.target is not None:
            tv = next((v for v in targets if v.name == self.target), None)
            if tv is not None and tv.visible and project(yaw, pitch, tv.bearing_deg, tv.elevation_deg, hfov_deg):
                seen = tv
        if self.target is None:
            self.last_seen = t  # a patch of scene never hides
        elif seen is not None:
            vaz = wrap180(seen.bearing_deg - self.az_deg) / dt
            vel = (seen.elevation_deg - self.el_deg) / dt
            k = VELOCITY_ALPHA
            self.vaz_deg_s += k * (vaz - self.vaz_deg_s)
            self.vel_deg_s += k * (vel - self.vel_deg_s)
            self.az_deg, self.el_deg = seen.bearing_deg, seen.elevation_deg
            self.last_seen = t
        else:
            # Hidden: predict on the velocity estimate, as the camera's tracker coasts.
            self.az_deg = wrap180(self.az_deg + self.vaz_deg_s * dt)
            self.el_deg += self.vel_deg_s * dt
        if t - self.last_seen > self.traits.coast_s or not self._box(yaw, pitch, hfov_deg):
            self._lose(gimbal)
            return
        g = self.traits.gain_per_s
        lim = self.max_rate_deg_s
        rate_yaw = self.vaz_deg_s + g * wrap180(self.az_deg - yaw)
        rate_pitch = self.vel_deg_s + g * (self.el_deg - pitch)
        gimbal.rate("yaw", max(-lim, min(lim, rate_yaw)))
        gimbal.rate("pitch", max(-lim, min(lim, rate_pitch)))
        self.driving = True

    def _lose(self, gimbal: GimbalPhysics) -> None:
        self._release(gimbal)
        self.state, self.box = "lost", None
