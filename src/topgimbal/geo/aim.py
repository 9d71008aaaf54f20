"""Where the camera looks, and how to look at a place: pure geometry on a locally flat earth
(plenty for the few kilometres a gimbal camera sees), scaled by the WGS84 ellipsoid's radii of
curvature (topgimbal.geo.earth, the one earth model)."""

from __future__ import annotations

import math

from .earth import metres_per_degree, wrap180
from .frames import Geodetic, LocalFrame
from .terrain import ellipsoid_intersect


def offset_m(a: Geodetic, b: Geodetic) -> tuple[float, float, float]:
    """North, east, up metres from `a` to `b`."""
    m_lat, m_lon = metres_per_degree((a.lat_deg + b.lat_deg) / 2.0)
    return (b.lat_deg - a.lat_deg) * m_lat, wrap180(b.lon_deg - a.lon_deg) * m_lon, b.alt_m - a.alt_m


def look_at(camera: Geodetic, vehicle_yaw_deg: float, target: Geodetic) -> tuple[float, float]:
    """Body-frame (yaw, pitch) in degrees that point the camera at `target` (yaw relative to the
    vehicle's heading, right-positive, -180..180; pitch up-positive)."""
    north, east, up = offset_m(camera, target)
    bearing = math.degrees(math.atan2(east, north))
    ground = math.hypot(north, east)
    pitch = math.degrees(math.atan2(up, ground)) if ground > 0 or up != 0 else 0.0
    yaw = wrap180(bearing - vehicle_yaw_deg)
    return yaw, pitch


def ground_point(camera: Geodetic, bearing_deg: float, pitch_deg: float, ground_alt_m: float) -> Geodetic | None:
    """Where a ray from `camera` (earth-frame bearing, pitch up-positive) meets ground at
    `ground_alt_m` (a height above the WGS84 ellipsoid, as topgimbal.geo's flat ground); None when it
    looks at or above the horizon or the camera is not above ground."""
    if camera.alt_m - ground_alt_m <= 0 or pitch_deg >= -0.1:
        return None
    b, p = math.radians(bearing_deg), math.radians(pitch_deg)
    d = (math.cos(p) * math.cos(b), math.cos(p) * math.sin(b), math.sin(p))
    frame = LocalFrame(Geodetic(camera.lat_deg, camera.lon_deg, camera.alt_m))
    t = ellipsoid_intersect(frame, d, ground_alt_m, math.inf)
    if t is None:
        return None
    hit = frame.to_geodetic(d[0] * t, d[1] * t, d[2] * t)
    return Geodetic(hit.lat_deg, hit.lon_deg, ground_alt_m)
