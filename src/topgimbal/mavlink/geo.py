"""Where the camera looks, and how to look at a place: pure geometry on a locally flat earth
(plenty for the few kilometres a gimbal camera sees)."""

from __future__ import annotations

import math
from dataclasses import dataclass

EARTH_RADIUS_M = 6371008.8


@dataclass(frozen=True)
class Position:
    lat_deg: float
    lon_deg: float
    alt_m: float  # above mean sea level


def offset_m(a: Position, b: Position) -> tuple[float, float, float]:
    """North, east, up metres from `a` to `b`."""
    north = math.radians(b.lat_deg - a.lat_deg) * EARTH_RADIUS_M
    dlon = (b.lon_deg - a.lon_deg + 180.0) % 360.0 - 180.0
    east = math.radians(dlon) * EARTH_RADIUS_M * math.cos(math.radians((a.lat_deg + b.lat_deg) / 2.0))
    return north, east, b.alt_m - a.alt_m


def look_at(camera: Position, vehicle_yaw_deg: float, target: Position) -> tuple[float, float]:
    """Body-frame (yaw, pitch) in degrees that point the camera at `target` (yaw relative to the
    vehicle's heading, right-positive, -180..180; pitch up-positive)."""
    north, east, up = offset_m(camera, target)
    bearing = math.degrees(math.atan2(east, north))
    ground = math.hypot(north, east)
    pitch = math.degrees(math.atan2(up, ground)) if ground > 0 or up != 0 else 0.0
    yaw = (bearing - vehicle_yaw_deg + 180.0) % 360.0 - 180.0
    return yaw, pitch


def ground_point(camera: Position, bearing_deg: float, pitch_deg: float, ground_alt_m: float) -> Position | None:
    """Where a ray from `camera` (earth-frame bearing, pitch up-positive) meets flat ground at
    `ground_alt_m`; None when it looks at or above the horizon or the camera is not above ground."""
    height = camera.alt_m - ground_alt_m
    if height <= 0 or pitch_deg >= -0.1:
        return None
    ground = height / math.tan(math.radians(-pitch_deg))
    north = ground * math.cos(math.radians(bearing_deg))
    east = ground * math.sin(math.radians(bearing_deg))
    lat = camera.lat_deg + math.degrees(north / EARTH_RADIUS_M)
    lon = camera.lon_deg + math.degrees(east / (EARTH_RADIUS_M * max(1e-9, math.cos(math.radians(camera.lat_deg)))))
    return Position(lat, (lon + 180.0) % 360.0 - 180.0, ground_alt_m)
