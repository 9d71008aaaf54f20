"""The simulator's ground when it is given a terrain model (`sim --terrain DEM.tif`): the laser
reads the true distance along the gimbal's ray from the vehicle position the host fed.

The truth is found here by its own method, not topgimbal.geo's exact intersection: a march in
fine fixed steps over the model's bilinear heights, then bisection of the crossing, so tests that
compare `locate` with the simulated laser compare two independent computations."""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path

from ..geo.earth import ned_up_to_geodetic
from ..geo.terrain import GridTerrain

STEP_M = 0.5  # a bilinear 10 m grid has no feature a 0.5 m step could step over but a razor crest


@dataclass(frozen=True)
class TerrainGround:
    grid: GridTerrain

    @classmethod
    def load(cls, path: str | Path) -> TerrainGround:
        from ..geo.dem import load_dem

        return cls(load_dem(path))

    def height_m(self, lat_deg: float, lon_deg: float) -> float | None:
        return self.grid.height_m(lat_deg, lon_deg)

    def slant_range(
        self, lat_deg: float, lon_deg: float, alt_m: float, bearing_deg: float, pitch_deg: float, max_m: float
    ) -> float | None:
        """Distance from the camera to the ground along an earth-frame ray, or None (misses
        within `max_m`, leaves the model, or the camera is under the model's ground)."""
        b, p = math.radians(bearing_deg), math.radians(pitch_deg)
        dn, de, dz = math.cos(p) * math.cos(b), math.cos(p) * math.sin(b), math.sin(p)
        origin = (lat_deg, lon_deg, alt_m)

        def above(t: float) -> float | None:
            # the ray's point on the WGS84 ellipsoid (heights above it), against the model's ground
            lat, lon, h_ray = ned_up_to_geodetic(origin, dn * t, de * t, dz * t)
            h = self.grid.height_m(lat, lon)
            return None if h is None else h_ray - h

        first = above(0.0)
        if first is None or first <= 0:
            return None
        prev_t, t = 0.0, STEP_M
        while t <= max_m + STEP_M:
            g = above(t)
            if g is None:
                return None
            if g <= 0:
                lo, hi = prev_t, t
                for _ in range(30):  # 0.5 m / 2^30: far below the 0.1 m the laser reports
                    mid = 0.5 * (lo + hi)
                    gm = above(mid)
                    lo, hi = (mid, hi) if gm is not None and gm > 0 else (lo, mid)
                return hi if hi <= max_m else None
            if dz >= 0 and alt_m + dz * t > self.grid.max_height_m:
                return None
            prev_t, t = t, t + STEP_M
        return None
