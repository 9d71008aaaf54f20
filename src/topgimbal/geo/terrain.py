"""A terrain model and the exact intersection of a ray with it.

The model is a grid of heights (metres above mean sea level) at the centres of a raster aligned
with latitude and longitude, as GeoTIFF DEMs in geographic coordinates are (SRTM, Copernicus,
ALOS); between centres the height is bilinear. The ray is traversed cell by cell (Amanatides and
Woo's walk, no fixed step): inside a cell the bilinear surface along a straight line is a
quadratic in the distance, and so is the earth's curvature drop, so the first crossing is the
smallest root of one quadratic per cell, exact to floating point. Pure: no I/O (`dem.py` reads a
file into this)."""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from typing import Protocol

from .earth import radii_m
from .frames import LocalFrame, Vec


class Terrain(Protocol):
    """What the geolocation needs from a terrain model."""

    @property
    def vertical_error_m(self) -> float: ...  # 1-sigma of its heights

    def height_m(self, lat_deg: float, lon_deg: float) -> float | None: ...

    def intersect(self, frame: LocalFrame, origin: Vec, direction: Vec, max_range_m: float) -> float | None: ...


def _finite(h: float) -> bool:
    return h == h and math.isfinite(h)


@dataclass(frozen=True)
class GridTerrain:
    """Heights `rows[r][c]` at latitude `lat0_deg + r * dlat_deg`, longitude `lon0_deg + c * dlon_deg`
    (pixel centres; `dlat_deg` is negative for the usual north-up raster). NaN marks no data."""

    rows: Sequence[Sequence[float]]
    lat0_deg: float
    lon0_deg: float
    dlat_deg: float
    dlon_deg: float
    vertical_error_m: float = 2.0  # 1-sigma of the model's heights (documented by the DEM's maker)
    curvature: bool = True  # the ground falls away as distance^2 / 2R from the tangent plane
    _max_m: float = field(init=False, repr=False, compare=False)

    def __post_init__(self) -> None:
        if self.dlat_deg == 0 or self.dlon_deg == 0 or len(self.rows) < 2 or len(self.rows[0]) < 2:
            raise ValueError("a terrain grid needs at least 2x2 heights and non-zero spacing")
        object.__setattr__(self, "_max_m", _max_height(self.rows))

    @property
    def shape(self) -> tuple[int, int]:
        return len(self.rows), len(self.rows[0])

    @property
    def max_height_m(self) -> float:
        return self._max_m

    def _cell(self, c: int, r: int) -> tuple[float, float, float, float] | None:
        rows = self.rows
        h00, h10 = float(rows[r][c]), float(rows[r][c + 1])
        h01, h11 = float(rows[r + 1][c]), float(rows[r + 1][c + 1])
        if not (_finite(h00) and _finite(h10) and _finite(h01) and _finite(h11)):
            return None
        return h00, h10, h01, h11

    def height_m(self, lat_deg: float, lon_deg: float) -> float | None:
        """Bilinear height at a place, or None outside the grid or over no data."""
        u = (lon_deg - self.lon0_deg) / self.dlon_deg
        v = (lat_deg - self.lat0_deg) / self.dlat_deg
        nr, nc = self.shape
        if not (0.0 <= u <= nc - 1 and 0.0 <= v <= nr - 1):
            return None
        c, r = min(int(u), nc - 2), min(int(v), nr - 2)
        cell = self._cell(c, r)
        if cell is None:
            return None
        h00, h10, h01, h11 = cell
        fu, fv = u - c, v - r
        return h00 * (1 - fu) * (1 - fv) + h10 * fu * (1 - fv) + h01 * (1 - fu) * fv + h11 * fu * fv

    def intersect(self, frame: LocalFrame, origin: Vec, direction: Vec, max_range_m: float) -> float | None:
        """Distance along the unit `direction` (north, east, up) from `origin` (metres in `frame`)
        to the first point where the ray meets the ground, or None (misses within `max_range_m`,
        leaves the grid, or crosses no data first)."""
        t = self._walk(frame, origin, direction, max_range_m)
        if t is None or origin != (0.0, 0.0, 0.0):
            return t
        return refine_on_ellipsoid(frame, direction, self.height_m, t)

    def _walk(self, frame: LocalFrame, origin: Vec, direction: Vec, max_range_m: float) -> float | None:
        """The cell walk: latitude and longitude taken as linear in the distance (the ellipsoid's
        radii of curvature at the origin) and the ground as falling by distance^2 / 2R, which is
        within centimetres of the ellipsoid over a few kilometres; intersect() then makes it exact."""
        n0, e0, z0 = origin
        dn, de, dz = direction
        m_lat, m_lon = frame.m_per_deg_lat, frame.m_per_deg_lon
        # grid coordinates (u columns, v rows) are linear in the distance t along the ray
        lat_o = frame.origin.lat_deg + n0 / m_lat
        lon_o = frame.origin.lon_deg + e0 / m_lon
        u0 = (lon_o - self.lon0_deg) / self.dlon_deg
        v0 = (lat_o - self.lat0_deg) / self.dlat_deg
        du = de / m_lon / self.dlon_deg
        dv = dn / m_lat / self.dlat_deg
        nr, nc = self.shape
        t0, t1 = _clip(u0, du, 0.0, nc - 1.0, 0.0, max_range_m)
        t0, t1 = _clip(v0, dv, 0.0, nr - 1.0, t0, t1)
        if t0 > t1:
            return None
        base_alt = frame.origin.alt_m
        k = 1.0 / (2.0 * math.sqrt(math.prod(radii_m(frame.origin.lat_deg)))) if self.curvature else 0.0
        eps = 1e-9
        t = t0
        u, v = u0 + du * t, v0 + dv * t
        c = min(max(math.floor(u + (eps if du > 0 else -eps if du < 0 else 0)), 0), nc - 2)
        r = min(max(math.floor(v + (eps if dv > 0 else -eps if dv < 0 else 0)), 0), nr - 2)
        step_c = 1 if du > 0 else -1
        step_r = 1 if dv > 0 else -1
        while t <= t1:
            # where the ray leaves this cell
            tu = ((c + (1 if du > 0 else 0)) - u0) / du if du != 0 else math.inf
            tv = ((r + (1 if dv > 0 else 0)) - v0) / dv if dv != 0 else math.inf
            t_exit = min(tu, tv, t1)
            cell = self._cell(c, r)
            if cell is None:
                return None  # a hole in the model: say nothing rather than look through it
            hit = _cell_hit(cell, c, r, u0, v0, du, dv, n0, e0, z0 + base_alt, dn, de, dz, k, t, t_exit)
            if hit is not None:
                return hit
            if dz >= 0 and z0 + base_alt + dz * t_exit > self._max_m:
                return None  # climbing above the highest point: it can never come down
            if t_exit >= t1:
                return None
            if tu <= tv:
                c += step_c
            if tv <= tu:
                r += step_r
            if not (0 <= c <= nc - 2 and 0 <= r <= nr - 2):
                return None
            t = t_exit
        return None


def _max_height(rows: Sequence[Sequence[float]]) -> float:
    if hasattr(rows, "__array__"):  # a numpy array (from dem.py): let numpy scan it
        import numpy as np  # only when given an array, so numpy is there

        with np.errstate(all="ignore"):
            m = np.nanmax(np.asarray(rows)) if np.isfinite(np.asarray(rows)).any() else -math.inf
        return float(m)
    finite = [float(h) for row in rows for h in row if _finite(float(h))]
    return max(finite) if finite else -math.inf


def _clip(p0: float, dp: float, lo: float, hi: float, t0: float, t1: float) -> tuple[float, float]:
    """Narrow [t0, t1] to where p0 + dp t lies in [lo, hi]."""
    if dp == 0:
        return (t0, t1) if lo <= p0 <= hi else (1.0, 0.0)
    a, b = (lo - p0) / dp, (hi - p0) / dp
    if a > b:
        a, b = b, a
    return max(t0, a), min(t1, b)


def _cell_hit(
    cell: tuple[float, float, float, float],
    c: int,
    r: int,
    u0: float,
    v0: float,
    du: float,
    dv: float,
    n0: float,
    e0: float,
    z0: float,
    dn: float,
    de: float,
    dz: float,
    k: float,
    ta: float,
    tb: float,
) -> float | None:
    """Smallest t in [ta, tb] where ray height - (bilinear height - curvature drop) reaches 0."""
    h00, h10, h01, h11 = cell
    a, b, cc, d = h00, h10 - h00, h01 - h00, h00 - h10 - h01 + h11
    fu0, fv0 = u0 - c, v0 - r
    # h(t) = a + b fu + cc fv + d fu fv with fu = fu0 + du t, fv = fv0 + dv t
    h2 = d * du * dv
    h1 = b * du + cc * dv + d * (fu0 * dv + fv0 * du)
    h0 = a + b * fu0 + cc * fv0 + d * fu0 * fv0
    # curvature: the ground drops k * (n^2 + e^2) below the tangent plane
    q2 = k * (dn * dn + de * de)
    q1 = k * 2.0 * (n0 * dn + e0 * de)
    q0 = k * (n0 * n0 + e0 * e0)
    # g(t) = z0 + dz t - h(t) + curvature drop; a hit where g falls to 0
    A = -h2 + q2  # noqa: N806
    B = dz - h1 + q1  # noqa: N806
    C = z0 - h0 + q0  # noqa: N806

    def g(t: float) -> float:
        return (A * t + B) * t + C

    if g(ta) <= 0.0:
        return ta
    roots: list[float] = []
    if abs(A) < 1e-15:
        if B != 0:
            roots.append(-C / B)
    else:
        disc = B * B - 4 * A * C
        if disc >= 0:
            s = math.sqrt(disc)
            q = -0.5 * (B + math.copysign(s, B))  # the stable form
            roots += [q / A] + ([C / q] if q != 0 else [])
    inside = [t for t in roots if ta <= t <= tb]
    return min(inside) if inside else None


def refine_on_ellipsoid(
    frame: LocalFrame, direction: Vec, ground_m: Callable[[float, float], float | None], t: float
) -> float:
    """`t` (a crossing found on a local approximation of the earth) made exact: the distance
    along the ray where its height above the WGS84 ellipsoid equals the ground's there, by
    bisection in a bracket about `t`; `t` itself when no clean bracket is found (a crossing that
    grazes a ridge, or a hole in the model close by)."""

    def g(s: float) -> float | None:
        p = frame.to_geodetic(direction[0] * s, direction[1] * s, direction[2] * s)
        h = ground_m(p.lat_deg, p.lon_deg)
        return None if h is None else p.alt_m - h

    w = max(1.0, 0.01 * t)
    a, b = max(0.0, t - w), t + w
    ga, gb = g(a), g(b)
    if ga is None or gb is None or ga <= 0.0 or gb > 0.0:
        return t
    for _ in range(60):
        m = 0.5 * (a + b)
        gm = g(m)
        if gm is None:
            return t
        a, b = (m, b) if gm > 0.0 else (a, m)
        if b - a < 1e-6:
            break
    return b


def ellipsoid_intersect(frame: LocalFrame, direction: Vec, ground_alt_m: float, max_range_m: float) -> float | None:
    """Distance along the unit `direction` from the frame's origin to where the ray comes down to
    `ground_alt_m` above the WGS84 ellipsoid (flat ground that follows the earth's curve), or None
    (looking at or above the horizon, the origin not above that height, or beyond `max_range_m`)."""
    t = flat_intersect(frame.origin.alt_m, ground_alt_m, direction, max_range_m * 2.0)
    if t is None:
        return None
    for _ in range(20):  # Newton on the exact height: two or three steps from the plane's answer
        g = frame.height_along(direction, t) - ground_alt_m
        slope = (frame.height_along(direction, t + 0.5) - frame.height_along(direction, t - 0.5)) / 1.0
        if slope >= 0.0:
            return None  # the ray no longer comes down towards the surface: it grazes the horizon
        step = g / slope
        t -= step
        if t <= 0.0:
            return None
        if abs(step) < 1e-6:
            break
    return t if t <= max_range_m else None


def flat_intersect(origin_up_m: float, ground_up_m: float, direction: Vec, max_range_m: float) -> float | None:
    """Distance along `direction` to the horizontal plane `ground_up_m` (local up metres)."""
    dz = direction[2]
    height = origin_up_m - ground_up_m
    if height <= 0 or dz >= -1e-6:
        return None
    t = height / -dz
    return t if t <= max_range_m else None
