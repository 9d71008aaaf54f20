"""The lens model: fields of view at a zoom, and pixels <-> earth-frame bearings for a camera
pointed at (yaw, pitch, roll). Pure; the one owner of the pinhole (client, MAVLink, tracking and
the renderer read it here; `topgimbal.video.lens` re-exports it for code that imported it there)."""

from __future__ import annotations

import math
from dataclasses import dataclass

from .earth import wrap180

Vec = tuple[float, float, float]


def hfov_at(hfov_1x_deg: float, zoom_x: float) -> float:
    """Horizontal field of view at a magnification (a pinhole: the focal length scales)."""
    z = max(1.0, float(zoom_x))
    return math.degrees(2.0 * math.atan(math.tan(math.radians(hfov_1x_deg) / 2.0) / z))


def vfov_for(hfov_deg: float, width_px: int, height_px: int) -> float:
    """Vertical field of view of a pinhole camera with this horizontal one and picture size."""
    return math.degrees(2.0 * math.atan(math.tan(math.radians(hfov_deg) / 2.0) * height_px / width_px))


def focal_px(width_px: int, hfov_deg: float) -> float:
    return (width_px / 2.0) / math.tan(math.radians(hfov_deg) / 2.0)


def basis(yaw_deg: float, pitch_deg: float, roll_deg: float) -> tuple[Vec, Vec, Vec]:
    """Forward, right and up unit vectors of a camera, in a world frame x north, y east, z up.
    Yaw is right-positive (a bearing), pitch up-positive, roll right-positive (right side down)."""
    y, p, r = (math.radians(a) for a in (yaw_deg, pitch_deg, roll_deg))
    fwd = (math.cos(p) * math.cos(y), math.cos(p) * math.sin(y), math.sin(p))
    right0 = (-math.sin(y), math.cos(y), 0.0)
    up0 = (-math.sin(p) * math.cos(y), -math.sin(p) * math.sin(y), math.cos(p))
    cr, sr = math.cos(r), math.sin(r)
    right = tuple(a * cr - b * sr for a, b in zip(right0, up0, strict=False))
    up = tuple(b * cr + a * sr for a, b in zip(right0, up0, strict=False))
    return fwd, right, up  # type: ignore[return-value]


def direction(az_deg: float, el_deg: float) -> Vec:
    a, e = math.radians(az_deg), math.radians(el_deg)
    return (math.cos(e) * math.cos(a), math.cos(e) * math.sin(a), math.sin(e))


@dataclass(frozen=True)
class PixelView:
    """Where a camera looks and how wide: enough to map pixels to bearings and back (by its role:
    a picture's pixels against bearings; `geo.View` is the locator's instant)."""

    yaw_deg: float
    pitch_deg: float
    roll_deg: float
    hfov_deg: float
    width_px: int
    height_px: int

    @property
    def focal_px(self) -> float:
        return focal_px(self.width_px, self.hfov_deg)

    def project(self, az_deg: float, el_deg: float) -> tuple[float, float] | None:
        """Pixel (x, y) of an earth-frame direction, or None behind the camera."""
        fwd, right, up = basis(self.yaw_deg, self.pitch_deg, self.roll_deg)
        d = direction(az_deg, el_deg)
        zc = _dot(d, fwd)
        if zc <= 1e-6:
            return None
        f = self.focal_px
        return self.width_px / 2.0 + f * _dot(d, right) / zc, self.height_px / 2.0 - f * _dot(d, up) / zc

    def angles_at(self, x_px: float, y_px: float) -> tuple[float, float]:
        """Earth-frame (bearing, elevation) in degrees of what is at pixel (x, y)."""
        fwd, right, up = basis(self.yaw_deg, self.pitch_deg, self.roll_deg)
        f = self.focal_px
        a = (x_px - self.width_px / 2.0) / f
        b = (self.height_px / 2.0 - y_px) / f
        ray = tuple(fw + a * r + b * u for fw, r, u in zip(fwd, right, up, strict=False))
        n = math.sqrt(sum(c * c for c in ray))
        az = math.degrees(math.atan2(ray[1], ray[0]))
        el = math.degrees(math.asin(max(-1.0, min(1.0, ray[2] / n))))
        return wrap180(az), el


def _dot(a: Vec, b: Vec) -> float:
    return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]


View = PixelView  # the name video.lens and track had
