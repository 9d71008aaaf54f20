"""Where the camera looks: the point the optical axis (or any pixel) meets, on the laser's range,
on a terrain model or on flat ground, in that order of trust, with which it was and a 1-sigma
horizontal error estimate. Pure geometry in user units; the caller supplies the numbers."""

from __future__ import annotations

import math
from dataclasses import dataclass, replace
from typing import Literal

from .frames import (
    Attitude,
    Geodetic,
    LocalFrame,
    Pointing,
    Vec,
    bearing_elevation,
    camera_matrix,
    column,
    ned_to_neu,
)
from .optics import hfov_at
from .terrain import Terrain, ellipsoid_intersect

Source = Literal["laser+terrain", "laser", "terrain", "flat"]
DEFAULT_MAX_RANGE_M = 10_000.0


@dataclass(frozen=True)
class Uncertainty:
    """1-sigma errors of the inputs (the error estimate propagates them to first order)."""

    angle_deg: float = 0.2  # vehicle attitude and gimbal angles together
    position_m: float = 1.5  # vehicle horizontal position (GNSS)
    altitude_m: float = 2.0  # vehicle altitude (MSL)
    laser_m: float = 1.0  # rangefinder (TOPOTEK and SkyDroid LRF modules: about 1 m)
    flat_ground_m: float = 10.0  # how far real ground strays from the flat plane assumed without a model


@dataclass(frozen=True)
class View:
    """One instant: where the vehicle is, how it and the gimbal are turned, how wide the lens sees."""

    position: Geodetic
    attitude: Attitude
    gimbal: Pointing
    hfov_deg: float = 60.0
    vfov_deg: float = 34.0


@dataclass(frozen=True)
class Fix:
    lat_deg: float
    lon_deg: float
    alt_m: float  # MSL
    range_m: float  # slant range from the camera
    source: Source
    error_m: float  # 1-sigma horizontal error estimate
    bearing_deg: float  # earth-frame direction of the ray
    elevation_deg: float

    def as_dict(self) -> dict[str, object]:
        return {
            "lat_deg": round(self.lat_deg, 7),
            "lon_deg": round(self.lon_deg, 7),
            "alt_m": round(self.alt_m, 2),
            "range_m": round(self.range_m, 2),
            "source": self.source,
            "error_m": round(self.error_m, 2),
            "bearing_deg": round(self.bearing_deg, 3),
            "elevation_deg": round(self.elevation_deg, 3),
        }


def ray(view: View, x: float = 0.0, y: float = 0.0) -> Vec:
    """Unit earth-frame direction (north, east, up) of the picture point (x, y): -1..1 from the
    left to the right edge and from the top to the bottom edge; (0, 0) is the optical axis."""
    m = camera_matrix(view.attitude, view.gimbal)
    fwd, right, down = column(m, 0), column(m, 1), column(m, 2)
    a = x * math.tan(math.radians(view.hfov_deg) / 2.0)
    b = y * math.tan(math.radians(view.vfov_deg) / 2.0)
    d = tuple(f + a * r + b * w for f, r, w in zip(fwd, right, down, strict=True))
    n = math.sqrt(sum(c * c for c in d))
    return ned_to_neu((d[0] / n, d[1] / n, d[2] / n))


def _surface_sine(terrain: Terrain | None, p: Geodetic, d: Vec) -> float:
    """Sine of the grazing angle between the ray and the ground at `p` (terrain slope counted)."""
    normal: Vec = (0.0, 0.0, 1.0)
    if terrain is not None:
        step_m = 5.0
        frame = LocalFrame(p)
        hn = terrain.height_m(*_at(frame, step_m, 0.0))
        hs = terrain.height_m(*_at(frame, -step_m, 0.0))
        he = terrain.height_m(*_at(frame, 0.0, step_m))
        hw = terrain.height_m(*_at(frame, 0.0, -step_m))
        if None not in (hn, hs, he, hw):
            gn = (hn - hs) / (2 * step_m)  # type: ignore[operator]
            ge = (he - hw) / (2 * step_m)  # type: ignore[operator]
            k = math.sqrt(gn * gn + ge * ge + 1.0)
            normal = (-gn / k, -ge / k, 1.0 / k)
    return max(0.05, abs(sum(a * b for a, b in zip(d, normal, strict=True))))


def _at(frame: LocalFrame, north_m: float, east_m: float) -> tuple[float, float]:
    g = frame.to_geodetic(north_m, east_m, 0.0)
    return g.lat_deg, g.lon_deg


def locate(
    view: View,
    *,
    terrain: Terrain | None = None,
    laser_range_m: float | None = None,
    ground_alt_m: float | None = None,
    x: float = 0.0,
    y: float = 0.0,
    max_range_m: float = DEFAULT_MAX_RANGE_M,
    uncertainty: Uncertainty = Uncertainty(),
) -> Fix | None:
    """The point the picture point (x, y) looks at, or None when nothing is known to be hit (sky,
    off the terrain model, no flat ground given). The laser measures along the optical axis only,
    so it is used for (0, 0) alone; when it and the terrain agree within their errors the two
    ranges are fused along the ray (inverse-variance), when they disagree the laser wins (it hit
    something the model lacks: a tree, a roof, a vehicle)."""
    frame = LocalFrame(view.position)
    d = ray(view, x, y)
    bearing, elevation = bearing_elevation(d)
    u = uncertainty
    s_ang = math.radians(u.angle_deg)
    on_axis = x == 0.0 and y == 0.0
    laser = laser_range_m if on_axis and laser_range_m is not None and laser_range_m > 0 else None

    t_dem = terrain.intersect(frame, (0.0, 0.0, 0.0), d, max_range_m) if terrain is not None else None
    if t_dem is not None and t_dem <= 0.0:
        t_dem = None  # the camera is below the model's ground: the model or the altitude is wrong

    def fix(t: float, source: Source, along_sigma_m: float, surface_sigma_m: float | None) -> Fix:
        p = frame.to_geodetic(d[0] * t, d[1] * t, d[2] * t)
        cos_el = math.cos(math.radians(elevation))
        if surface_sigma_m is None:  # a measured range: the angle moves it sideways only
            horiz = math.sqrt(u.position_m**2 + (t * s_ang) ** 2 + (along_sigma_m * cos_el) ** 2)
        else:  # where a ray meets a surface: both errors are stretched by the grazing angle
            sin_g = _surface_sine(terrain if source == "terrain" else None, p, d)
            tan_g = sin_g / math.sqrt(max(1e-9, 1.0 - sin_g * sin_g))
            horiz = math.sqrt(u.position_m**2 + (t * s_ang / sin_g) ** 2 + (surface_sigma_m / tan_g) ** 2)
        return Fix(p.lat_deg, p.lon_deg, p.alt_m, t, source, horiz, bearing, elevation)

    if laser is not None:
        if t_dem is not None:
            sin_g = _surface_sine(terrain, frame.to_geodetic(*(c * t_dem for c in d)), d)
            s_v = math.hypot(terrain.vertical_error_m, u.altitude_m)  # type: ignore[union-attr]
            s_dem = math.hypot(s_v / sin_g, t_dem * s_ang * math.sqrt(max(0.0, 1 - sin_g**2)) / sin_g)
            if abs(laser - t_dem) <= 3.0 * math.hypot(u.laser_m, s_dem):
                w_l, w_d = 1.0 / u.laser_m**2, 1.0 / s_dem**2
                t = (laser * w_l + t_dem * w_d) / (w_l + w_d)
                return fix(t, "laser+terrain", 1.0 / math.sqrt(w_l + w_d), None)
        return fix(laser, "laser", u.laser_m, None)
    if t_dem is not None:
        s_v = math.hypot(terrain.vertical_error_m, u.altitude_m)  # type: ignore[union-attr]
        return fix(t_dem, "terrain", 0.0, s_v)
    if ground_alt_m is not None:
        t_flat = ellipsoid_intersect(frame, d, ground_alt_m, max_range_m)
        if t_flat is not None:
            return fix(t_flat, "flat", 0.0, math.hypot(u.flat_ground_m, u.altitude_m))
    return None


CORNERS = ((-1.0, -1.0), (1.0, -1.0), (1.0, 1.0), (-1.0, 1.0))


def footprint(
    view: View,
    *,
    terrain: Terrain | None = None,
    ground_alt_m: float | None = None,
    max_range_m: float = DEFAULT_MAX_RANGE_M,
    uncertainty: Uncertainty = Uncertainty(),
) -> list[Fix | None]:
    """Where the picture's four corners land (top-left, top-right, bottom-right, bottom-left);
    None for a corner above the horizon or off the model."""
    return [
        locate(
            view,
            terrain=terrain,
            ground_alt_m=ground_alt_m,
            x=cx,
            y=cy,
            max_range_m=max_range_m,
            uncertainty=uncertainty,
        )
        for cx, cy in CORNERS
    ]


def with_zoom(view: View, zoom_x: float) -> View:
    """The same view through a lens zoomed `zoom_x` times (a pinhole: tangents scale)."""
    return replace(view, hfov_deg=hfov_at(view.hfov_deg, zoom_x), vfov_deg=hfov_at(view.vfov_deg, zoom_x))
