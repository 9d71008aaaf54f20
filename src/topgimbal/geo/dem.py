"""Read a GeoTIFF DEM into a GridTerrain. rasterio (the `geo` extra) is imported here, lazily, so
the rest of the package needs nothing beyond the standard library."""

from __future__ import annotations

import math
from pathlib import Path

from ..errors import TopGimbalError
from .terrain import GridTerrain

MAX_CELLS = 64_000_000  # a 8000x8000 tile: ~0.5 GB as float64; larger models are refused, not swapped


class DemError(TopGimbalError, ValueError):
    """The file is not a DEM this package can use."""

    kind = "dem"


def load_dem(path: str | Path, *, vertical_error_m: float = 2.0, band: int = 1) -> GridTerrain:
    """Heights from band `band` of a GeoTIFF in geographic coordinates (EPSG:4326 or another
    lat/lon CRS), north-up; the file's nodata value becomes a hole. Raises DemError otherwise."""
    try:
        import rasterio  # optional dependency, imported on use
    except ImportError as e:  # pragma: no cover - depends on the installation
        raise DemError("reading a DEM needs rasterio: pip install 'topgimbal[geo]'") from e
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
    # pixel centres: (col + 0.5, row + 0.5) in the affine transform
    lon0, lat0 = t.c + 0.5 * t.a, t.f + 0.5 * t.e
    return GridTerrain(data, float(lat0), float(lon0), float(t.e), float(t.a), vertical_error_m=vertical_error_m)
