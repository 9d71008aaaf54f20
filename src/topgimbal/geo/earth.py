"""The earth model every part of topgimbal uses: the WGS84 ellipsoid (geodetic <-> ECEF <-> local
east/north/up tangent frames) and the angle wraps. One place, so that no module carries its own
radius or its own `% 360` (tests/test_architecture.py holds the rest of the code to that).

Heights are taken as heights above the ellipsoid's surface. The vehicle's and the ground's heights
both come as MSL here; the geoid's undulation between a camera and what it sees a few kilometres
away changes by centimetres, so treating MSL as ellipsoidal height locally costs nothing measurable
(the CoT `hae` field, which is absolute, adds the undulation where it is written)."""

from __future__ import annotations

import math

# WGS84 (NIMA TR8350.2)
WGS84_A_M = 6378137.0
WGS84_F = 1.0 / 298.257223563
WGS84_B_M = WGS84_A_M * (1.0 - WGS84_F)
WGS84_E2 = WGS84_F * (2.0 - WGS84_F)
# The mean radius (2a + b) / 3: only for rough figures (a rate of change, a search radius), never
# to place a point.
MEAN_RADIUS_M = (2.0 * WGS84_A_M + WGS84_B_M) / 3.0

Vec = tuple[float, float, float]


# -- angles ----------------------------------------------------------------------------------


def wrap180(deg: float) -> float:
    """An angle in [-180, 180)."""
    return (deg + 180.0) % 360.0 - 180.0


def wrap360(deg: float) -> float:
    """An angle in [0, 360)."""
    return deg % 360.0


# -- the ellipsoid ---------------------------------------------------------------------------


def radii_m(lat_deg: float) -> tuple[float, float]:
    """(meridian, prime vertical) radii of curvature at a latitude: metres per radian of latitude,
    and per radian of longitude divided by cos(latitude)."""
    s = math.sin(math.radians(lat_deg))
    w = math.sqrt(1.0 - WGS84_E2 * s * s)
    return WGS84_A_M * (1.0 - WGS84_E2) / (w * w * w), WGS84_A_M / w


def metres_per_degree(lat_deg: float) -> tuple[float, float]:
    """(north, east) metres per degree of latitude and of longitude at a latitude."""
    m, n = radii_m(lat_deg)
    return math.radians(m), math.radians(n) * max(1e-9, math.cos(math.radians(lat_deg)))


def to_ecef(lat_deg: float, lon_deg: float, h_m: float) -> Vec:
    la, lo = math.radians(lat_deg), math.radians(lon_deg)
    s = math.sin(la)
    n = WGS84_A_M / math.sqrt(1.0 - WGS84_E2 * s * s)
    return ((n + h_m) * math.cos(la) * math.cos(lo), (n + h_m) * math.cos(la) * math.sin(lo),
            (n * (1.0 - WGS84_E2) + h_m) * s)  # fmt: skip


def from_ecef(x: float, y: float, z: float) -> Vec:
    """(lat_deg, lon_deg, h_m) of an ECEF point: Bowring's start, then fixed-point iterations to
    well under a micrometre anywhere near the surface."""
    lon = math.atan2(y, x)
    p = math.hypot(x, y)
    if p < 1e-9:  # on the axis
        return (90.0 if z >= 0 else -90.0), math.degrees(lon), abs(z) - WGS84_B_M
    ep2 = WGS84_E2 / (1.0 - WGS84_E2)
    th = math.atan2(z * WGS84_A_M, p * WGS84_B_M)
    lat = math.atan2(z + ep2 * WGS84_B_M * math.sin(th) ** 3, p - WGS84_E2 * WGS84_A_M * math.cos(th) ** 3)
    h = 0.0
    for _ in range(4):
        s = math.sin(lat)
        n = WGS84_A_M / math.sqrt(1.0 - WGS84_E2 * s * s)
        h = p / math.cos(lat) - n if abs(lat) < math.radians(80) else z / s - n * (1.0 - WGS84_E2)
        lat = math.atan2(z, p * (1.0 - WGS84_E2 * n / (n + h)))
    return math.degrees(lat), math.degrees(lon), h


def _axes(lat_deg: float, lon_deg: float) -> tuple[Vec, Vec, Vec]:
    """North, east, up unit vectors (ECEF) of the tangent frame at a place."""
    la, lo = math.radians(lat_deg), math.radians(lon_deg)
    sla, cla, slo, clo = math.sin(la), math.cos(la), math.sin(lo), math.cos(lo)
    return (-sla * clo, -sla * slo, cla), (-slo, clo, 0.0), (cla * clo, cla * slo, sla)


def geodetic_to_ned_up(origin: Vec, lat_deg: float, lon_deg: float, h_m: float) -> Vec:
    """(north, east, up) metres of a place in the tangent frame at `origin` (lat, lon, h)."""
    o = to_ecef(*origin)
    p = to_ecef(lat_deg, lon_deg, h_m)
    d = (p[0] - o[0], p[1] - o[1], p[2] - o[2])
    n, e, u = _axes(origin[0], origin[1])
    return (sum(a * b for a, b in zip(n, d, strict=True)), sum(a * b for a, b in zip(e, d, strict=True)),
            sum(a * b for a, b in zip(u, d, strict=True)))  # fmt: skip


def ned_up_to_geodetic(origin: Vec, north_m: float, east_m: float, up_m: float) -> Vec:
    """(lat, lon, h) of the point (north, east, up) metres in the tangent frame at `origin`."""
    o = to_ecef(*origin)
    n, e, u = _axes(origin[0], origin[1])
    p = tuple(o[i] + north_m * n[i] + east_m * e[i] + up_m * u[i] for i in range(3))
    lat, lon, h = from_ecef(*p)
    return lat, wrap180(lon), h
