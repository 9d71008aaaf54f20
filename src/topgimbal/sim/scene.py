"""The world outside the camera: a synthetic thermal scene, flat ground for the rangefinder, and
the target solution (TOPOTEK §8.7). Pure functions of angles and positions."""

from __future__ import annotations

import math
from dataclasses import dataclass

from ..geo.earth import MEAN_RADIUS_M as EARTH_RADIUS_M
from ..geo.earth import wrap180

# One warm object on the ground; everything else is sky or ground at ambient temperature.
HOT_SPOT_YAW_DEG = 30.0
HOT_SPOT_PITCH_DEG = -20.0
HOT_SPOT_C = 85.0
HOT_SPOT_WIDTH_DEG = 4.0
SKY_C = -12.0
GROUND_C = 21.0
THERMAL_HFOV_DEG = 32.0
THERMAL_VFOV_DEG = 26.0
THERMAL_SIZE = (320, 256)  # §12.1 coordinates


def temperature_at(yaw_deg: float, pitch_deg: float) -> float:
    """Scene temperature (°C) in an earth-frame direction."""
    base = GROUND_C if pitch_deg < 0 else SKY_C + (GROUND_C - SKY_C) * math.exp(-pitch_deg / 3.0)
    dy = wrap180(yaw_deg - HOT_SPOT_YAW_DEG)
    dp = pitch_deg - HOT_SPOT_PITCH_DEG
    return base + (HOT_SPOT_C - GROUND_C) * math.exp(-(dy * dy + dp * dp) / (2 * HOT_SPOT_WIDTH_DEG**2))


@dataclass(frozen=True)
class ThermalFrame:
    hot_xy: tuple[int, int]
    hot_c: float
    cold_xy: tuple[int, int]
    cold_c: float
    center_c: float


def thermal_frame(yaw_deg: float, pitch_deg: float, zoom_x: float = 1.0, grid: int = 16) -> ThermalFrame:
    """Hottest, coldest and centre temperatures of the picture the camera sees (sampled grid)."""
    w, h = THERMAL_SIZE
    hfov, vfov = THERMAL_HFOV_DEG / zoom_x, THERMAL_VFOV_DEG / zoom_x
    hot = (-1e9, (w // 2, h // 2))
    cold = (1e9, (w // 2, h // 2))
    for i in range(grid + 1):
        for j in range(grid + 1):
            x, y = round(i * (w - 1) / grid), round(j * (h - 1) / grid)
            t = temperature_at(yaw_deg + (x / (w - 1) - 0.5) * hfov, pitch_deg - (y / (h - 1) - 0.5) * vfov)
            if t > hot[0]:
                hot = (t, (x, y))
            if t < cold[0]:
                cold = (t, (x, y))
    return ThermalFrame(
        hot[1], round(hot[0], 2), cold[1], round(cold[0], 2), round(temperature_at(yaw_deg, pitch_deg), 2)
    )


def area_temperature(
    yaw_deg: float, pitch_deg: float, x: int, y: int, w: int, h: int, size: tuple[int, int] = (640, 512)
) -> float:
    """Average temperature of a picture rectangle (TOPOTEK §12.3; a spot when w = h = 0)."""
    W, H = size  # noqa: N806
    cx, cy = x + w / 2.0, y + h / 2.0
    return round(
        temperature_at(yaw_deg + (cx / W - 0.5) * THERMAL_HFOV_DEG, pitch_deg - (cy / H - 0.5) * THERMAL_VFOV_DEG), 2
    )


def slant_range(height_m: float | None, pitch_deg: float) -> float | None:
    """Distance along the line of sight to flat ground `height_m` below, or None (looks at sky)."""
    if height_m is None or height_m <= 0 or pitch_deg >= -0.1:
        return None
    return height_m / math.sin(math.radians(-pitch_deg))


def target_position(
    lat_deg: float, lon_deg: float, bearing_deg: float, pitch_deg: float, range_m: float
) -> tuple[float, float]:
    """Latitude and longitude of the point `range_m` away along the line of sight (flat earth
    locally; plenty for a rangefinder's kilometre)."""
    ground = range_m * math.cos(math.radians(pitch_deg))
    north = ground * math.cos(math.radians(bearing_deg))
    east = ground * math.sin(math.radians(bearing_deg))
    lat = lat_deg + math.degrees(north / EARTH_RADIUS_M)
    lon = lon_deg + math.degrees(east / (EARTH_RADIUS_M * max(1e-9, math.cos(math.radians(lat_deg)))))
    lon = wrap180(lon)
    return round(max(-90.0, min(90.0, lat)), 6), round(lon, 6)
