"""Read a GeoTIFF DEM into a GridTerrain. rasterio (the `geo` extra) is imported here, lazily, so
the rest of the package needs nothing beyond the standard library."""

from __future__ import annotations

import math
import os
import stat
from pathlib import Path
from typing import Any

from ..errors import InputError
from .terrain import GridTerrain

MAX_CELLS = 64_000_000  # a 8000x8000 tile: ~0.5 GB as float64; larger models are refused, not swapped


class DemError(InputError, ValueError):
    """The file is not a DEM this package can use (the user's input: the CLI exits 2)."""

    kind = "dem"


def load_dem(path: str | Path, *, vertical_error_m: float = 2.0, band: int = 1) -> GridTerrain:
    """Heights from band `band` of a GeoTIFF in geographic coordinates (EPSG:4326 or another
    lat/lon CRS), north-up; the file's nodata value becomes a hole. Raises DemError otherwise."""
    try:
        import rasterio  # optional dependency, imported on use
    except ImportError as e:  # pragma: no cover - depends on the installation
        raise DemError("reading a DEM needs rasterio: pip install 'topgimbal[geo]'") from e
    _regular(path)
    try:
        with rasterio.open(path) as src:
            if src.crs is None or not src.crs.is_geographic:
                raise DemError(f"{path}: the DEM must be in latitude/longitude (EPSG:4326), not {src.crs}")
            t = src.transform
            if t.b != 0 or t.d != 0:
                raise DemError(f"{path}: rotated rasters are not supported")
            if src.width * src.height > MAX_CELLS:
                raise DemError(f"{path}: {src.width}x{src.height} cells exceed the limit of {MAX_CELLS}")
            data = src.read(band, masked=True).astype("float64").filled(math.nan)
    except DemError:
        raise
    except Exception as e:  # rasterio's errors for missing, corrupt or foreign files
        raise DemError(f"{path}: cannot read a DEM: {e}") from e
    _on_earth(path, t, src.width, src.height)
    # pixel centres: (col + 0.5, row + 0.5) in the affine transform
    lon0, lat0 = t.c + 0.5 * t.a, t.f + 0.5 * t.e
    return GridTerrain(data, float(lat0), float(lon0), float(t.e), float(t.a), vertical_error_m=vertical_error_m)


def _regular(path: str | Path) -> None:
    """A file that exists must be a regular one: GDAL would read /dev/zero or wait on a FIFO."""
    try:
        mode = os.stat(path).st_mode
    except OSError:
        return  # not there (or a GDAL virtual path): rasterio says what is wrong
    if not stat.S_ISREG(mode):
        raise DemError(f"{path}: not a regular file (a FIFO, a device or a folder): give a GeoTIFF file")


def _on_earth(path: str | Path, t: Any, width: int, height: int) -> None:
    """The grid's corners within latitude -90..90 and longitude -180..180 (finite)."""
    lons = (t.c, t.c + width * t.a)
    lats = (t.f, t.f + height * t.e)
    if not all(math.isfinite(v) for v in (*lons, *lats)) or t.a == 0 or t.e == 0:
        raise DemError(f"{path}: the DEM's grid is not finite (its geotransform: {tuple(t)[:6]})")
    if not all(-90.0 <= v <= 90.0 for v in lats) or not all(-180.0 <= v <= 180.0 for v in lons):
        raise DemError(
            f"{path}: the DEM reaches latitude {min(lats):g}..{max(lats):g}, longitude {min(lons):g}..{max(lons):g}; "
            "expected latitudes within -90..90 and longitudes within -180..180 (degrees)"
        )
