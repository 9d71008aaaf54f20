"""Positions and directions: a local east/north/up tangent frame about the camera on the WGS84
ellipsoid (earth.py: exact, geodetic <-> ECEF <-> tangent plane) and the rotation from the
vehicle's attitude and the gimbal's angles to an earth-frame ray."""

from __future__ import annotations

import math
from dataclasses import dataclass

from .earth import MEAN_RADIUS_M, geodetic_to_ned_up, metres_per_degree, ned_up_to_geodetic, wrap360

# Kept for what maps the synthetic landscape and the simulator's scenery onto latitude and longitude
# (their own definitions, not the earth's shape): the mean radius, from the one earth model.
EARTH_RADIUS_M = MEAN_RADIUS_M
M_PER_DEG = math.radians(1.0) * EARTH_RADIUS_M

Vec = tuple[float, float, float]
Mat = tuple[Vec, Vec, Vec]


@dataclass(frozen=True)
class Geodetic:
    lat_deg: float
    lon_deg: float
    alt_m: float  # above mean sea level (taken as above the ellipsoid locally: earth.py)


@dataclass(frozen=True)
class LocalFrame:
    """North, east, up metres about `origin`: the WGS84 tangent plane there (up along the
    ellipsoid's normal; a distant point on the same height is below the plane by the curvature)."""

    origin: Geodetic

    @property
    def _o(self) -> Vec:
        return (self.origin.lat_deg, self.origin.lon_deg, self.origin.alt_m)

    @property
    def m_per_deg_lat(self) -> float:
        return metres_per_degree(self.origin.lat_deg)[0]

    @property
    def m_per_deg_lon(self) -> float:
        return metres_per_degree(self.origin.lat_deg)[1]

    def to_local(self, lat_deg: float, lon_deg: float, alt_m: float) -> Vec:
        return geodetic_to_ned_up(self._o, lat_deg, lon_deg, alt_m)

    def to_geodetic(self, north_m: float, east_m: float, up_m: float) -> Geodetic:
        lat, lon, h = ned_up_to_geodetic(self._o, north_m, east_m, up_m)
        return Geodetic(lat, lon, h)

    def height_along(self, direction: Vec, t: float) -> float:
        """Height above the ellipsoid of the point `t` metres along the unit `direction` from the
        origin."""
        return self.to_geodetic(direction[0] * t, direction[1] * t, direction[2] * t).alt_m


# -- rotations: NED, ZYX Euler (yaw right-positive, pitch up-positive, roll right side down) ------


def euler_matrix(roll_deg: float, pitch_deg: float, yaw_deg: float) -> Mat:
    """Body-to-NED rotation of an aerospace ZYX Euler triple."""
    r, p, y = (math.radians(a) for a in (roll_deg, pitch_deg, yaw_deg))
    cr, sr, cp, sp, cy, sy = math.cos(r), math.sin(r), math.cos(p), math.sin(p), math.cos(y), math.sin(y)
    return (
        (cy * cp, cy * sp * sr - sy * cr, cy * sp * cr + sy * sr),
        (sy * cp, sy * sp * sr + cy * cr, sy * sp * cr - cy * sr),
        (-sp, cp * sr, cp * cr),
    )


def matmul(a: Mat, b: Mat) -> Mat:
    return tuple(tuple(sum(a[i][k] * b[k][j] for k in range(3)) for j in range(3)) for i in range(3))  # type: ignore[return-value]


def column(m: Mat, j: int) -> Vec:
    return (m[0][j], m[1][j], m[2][j])


def to_euler(m: Mat) -> tuple[float, float, float]:
    """(roll, pitch, yaw) degrees of a body-to-NED rotation."""
    pitch = math.degrees(math.asin(max(-1.0, min(1.0, -m[2][0]))))
    roll = math.degrees(math.atan2(m[2][1], m[2][2]))
    yaw = math.degrees(math.atan2(m[1][0], m[0][0]))
    return roll, pitch, yaw


def to_quaternion(m: Mat) -> tuple[float, float, float, float]:
    """(w, x, y, z) of a rotation matrix (MAVLink's order)."""
    tr = m[0][0] + m[1][1] + m[2][2]
    if tr > 0:
        s = math.sqrt(tr + 1.0) * 2
        return (0.25 * s, (m[2][1] - m[1][2]) / s, (m[0][2] - m[2][0]) / s, (m[1][0] - m[0][1]) / s)
    if m[0][0] > m[1][1] and m[0][0] > m[2][2]:
        s = math.sqrt(1.0 + m[0][0] - m[1][1] - m[2][2]) * 2
        return ((m[2][1] - m[1][2]) / s, 0.25 * s, (m[0][1] + m[1][0]) / s, (m[0][2] + m[2][0]) / s)
    if m[1][1] > m[2][2]:
        s = math.sqrt(1.0 + m[1][1] - m[0][0] - m[2][2]) * 2
        return ((m[0][2] - m[2][0]) / s, (m[0][1] + m[1][0]) / s, 0.25 * s, (m[1][2] + m[2][1]) / s)
    s = math.sqrt(1.0 + m[2][2] - m[0][0] - m[1][1]) * 2
    return ((m[1][0] - m[0][1]) / s, (m[0][2] + m[2][0]) / s, (m[1][2] + m[2][1]) / s, 0.25 * s)


@dataclass(frozen=True)
class Attitude:
    roll_deg: float = 0.0
    pitch_deg: float = 0.0
    yaw_deg: float = 0.0  # heading, degrees from north


@dataclass(frozen=True)
class Pointing:
    """The gimbal's angles; `earth_frame` says whether they are already earth-frame (a gimbal that
    reports earth-frame angles) or relative to the vehicle's body."""

    yaw_deg: float
    pitch_deg: float
    roll_deg: float = 0.0
    earth_frame: bool = False


def camera_matrix(vehicle: Attitude, gimbal: Pointing) -> Mat:
    """Camera-to-NED rotation: column 0 the optical axis, 1 the picture's right, 2 its down."""
    g = euler_matrix(gimbal.roll_deg, gimbal.pitch_deg, gimbal.yaw_deg)
    if gimbal.earth_frame:
        return g
    return matmul(euler_matrix(vehicle.roll_deg, vehicle.pitch_deg, vehicle.yaw_deg), g)


def ned_to_neu(v: Vec) -> Vec:
    return (v[0], v[1], -v[2])


def bearing_elevation(d_neu: Vec) -> tuple[float, float]:
    """Earth-frame bearing (0..360) and elevation (up-positive) in degrees of a direction."""
    n = math.sqrt(sum(c * c for c in d_neu))
    return wrap360(math.degrees(math.atan2(d_neu[1], d_neu[0]))), math.degrees(math.asin(d_neu[2] / n))
