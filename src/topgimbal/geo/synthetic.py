"""A synthetic landscape for tests, the benchmark and demonstrations: smooth hills and a sharp
ridge on a plain, as an analytic height function (the truth) and as a GeoTIFF DEM sampled from it
(what a user would have). Nothing is downloaded."""

from __future__ import annotations

import math
from pathlib import Path
from typing import Any

from .frames import M_PER_DEG

# (north_m, east_m, height_m, radius_m) of Gaussian hills about the landscape's origin
HILLS = (
    (400.0, 300.0, 80.0, 180.0),
    (-250.0, 500.0, 55.0, 120.0),
    (600.0, -400.0, 120.0, 260.0),
    (-500.0, -300.0, 40.0, 90.0),
    (150.0, -150.0, 25.0, 45.0),
)
BASE_M = 300.0  # the plain's height above mean sea level
RIDGE = (-100.0, 60.0, 30.0)  # a ridge running east-west at north -100 m: height, half-width


def height_at(north_m: float, east_m: float) -> float:
    """The true ground height (m MSL) `north_m`, `east_m` from the origin."""
    h = BASE_M
    for n, e, height, radius in HILLS:
        h += height * math.exp(-((north_m - n) ** 2 + (east_m - e) ** 2) / (2 * radius * radius))
    rn, rh, rw = RIDGE
    h += rh * max(0.0, 1.0 - abs(north_m - rn) / rw) * (1.0 if abs(east_m) < 900 else 0.0)
    # small undulations: what makes a 10 m grid differ from the truth
    h += 1.5 * math.sin(east_m / 23.0) * math.cos(north_m / 31.0)
    return h


def heights(north_m: Any, east_m: Any) -> Any:
    """`height_at` over numpy arrays (the same formula, vectorised)."""
    import numpy as np

    h = np.full(np.shape(north_m), BASE_M)
    for n, e, height, radius in HILLS:
        h = h + height * np.exp(-((north_m - n) ** 2 + (east_m - e) ** 2) / (2 * radius * radius))
    rn, rh, rw = RIDGE
    h = h + rh * np.maximum(0.0, 1.0 - np.abs(north_m - rn) / rw) * (np.abs(east_m) < 900)
    return h + 1.5 * np.sin(east_m / 23.0) * np.cos(north_m / 31.0)


def write_dem(
    path: str | Path, lat0_deg: float, lon0_deg: float, *, half_size_m: float = 2000.0, cell_m: float = 10.0
) -> Path:
    """Write the landscape about (lat0, lon0) as a float32 GeoTIFF (EPSG:4326, north-up) whose
    cells are `cell_m` on a side. Needs rasterio and numpy."""
    import numpy as np
    import rasterio
    from affine import Affine  # rasterio's own dependency

    m_lon = M_PER_DEG * math.cos(math.radians(lat0_deg))
    dlat, dlon = cell_m / M_PER_DEG, cell_m / m_lon
    n = round(2 * half_size_m / cell_m) + 1
    west, north = lon0_deg - (n / 2) * dlon, lat0_deg + (n / 2) * dlat
    lat = north - (np.arange(n) + 0.5) * dlat
    lon = west + (np.arange(n) + 0.5) * dlon
    nn, ee = np.meshgrid((lat - lat0_deg) * M_PER_DEG, (lon - lon0_deg) * m_lon, indexing="ij")
    data = heights(nn, ee).astype("float32")
    out = Path(path)
    with rasterio.open(
        out, "w", driver="GTiff", width=n, height=n, count=1, dtype="float32", crs="EPSG:4326",
        transform=Affine(dlon, 0.0, west, 0.0, -dlat, north), nodata=-9999.0,
    ) as dst:  # fmt: skip
        dst.write(data, 1)
    return out
