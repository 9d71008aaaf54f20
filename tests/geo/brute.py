"""An independent ray cast for the tests: samples the raster read straight from the file with its
own bilinear interpolation, places the ray's points on the WGS84 ellipsoid with pymap3d (not the
product's earth model), marches in fine fixed steps, then bisects the crossing."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pymap3d
import rasterio


class BruteCaster:
    def __init__(self, path: Path) -> None:
        with rasterio.open(path) as src:
            self.z = src.read(1).astype("float64")
            self.t = src.transform

    def height(self, lat: np.ndarray, lon: np.ndarray) -> np.ndarray:
        t = self.t
        u = (np.asarray(lon) - t.c) / t.a - 0.5  # pixel centres at +0.5
        v = (np.asarray(lat) - t.f) / t.e - 0.5
        self.inside = (u >= 0) & (u <= self.z.shape[1] - 1) & (v >= 0) & (v <= self.z.shape[0] - 1)
        c = np.clip(np.floor(u).astype(int), 0, self.z.shape[1] - 2)
        r = np.clip(np.floor(v).astype(int), 0, self.z.shape[0] - 2)
        fu, fv = u - c, v - r
        z = self.z
        return (
            z[r, c] * (1 - fu) * (1 - fv)
            + z[r, c + 1] * fu * (1 - fv)
            + z[r + 1, c] * (1 - fu) * fv
            + z[r + 1, c + 1] * fu * fv
        )

    def _above(self, lat0: float, lon0: float, alt0: float, d: tuple[float, float, float], t: np.ndarray) -> np.ndarray:
        n, e, up = d[0] * t, d[1] * t, d[2] * t
        lat, lon, h = pymap3d.enu2geodetic(e, n, up, lat0, lon0, alt0)  # heights above the ellipsoid
        return np.asarray(h) - self.height(np.asarray(lat), np.asarray(lon))

    def cast(
        self, lat0: float, lon0: float, alt0: float, d: tuple[float, float, float], max_m: float, step_m: float = 0.25
    ) -> float | None:
        t = np.arange(0.0, max_m, step_m)
        g = self._above(lat0, lon0, alt0, d, t)
        below = np.nonzero((g <= 0) | ~self.inside)[0]
        if len(below) == 0 or not self.inside[below[0]]:
            return None  # misses, or leaves the model first
        i = int(below[0])
        lo, hi = float(t[i - 1]), float(t[i])
        for _ in range(40):
            mid = 0.5 * (lo + hi)
            if self._above(lat0, lon0, alt0, d, np.array([mid]))[0] > 0:
                lo = mid
            else:
                hi = mid
        return hi
