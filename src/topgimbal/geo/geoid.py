"""Height above the WGS84 ellipsoid from height above mean sea level: h = H + N, N the EGM96 geoid
undulation (-107..+86 m) read from NGA's 15' grid through PROJ (pyproj). What MAVLink's `alt` and
the DEMs give is MSL; what Cursor-on-Target's `hae` means is the ellipsoid height.

The grid is not shipped: Debian's proj-data has it (`egm96_15.gtx`; PROJ's CDN names it
`us_nga_egm96_15.tif`). `ellipsoid_height()` is None without pyproj or the grid (logged once):
an unknown height is said so, never passed off as an ellipsoid height."""

from __future__ import annotations

import logging
import math
import os
from pathlib import Path
from typing import Any

log = logging.getLogger("topgimbal.geo")

GRID_NAMES = ("us_nga_egm96_15.tif", "egm96_15.gtx")  # the same grid: PROJ's current name, Debian's
SEARCH_DIRS = ("/usr/share/proj", "/usr/local/share/proj")


class Geoid:
    """EGM96 through one grid file: `undulation_m(lat, lon)`, `ellipsoid_height_m(lat, lon, msl)`."""

    def __init__(self, grid: Path) -> None:
        from pyproj import Transformer

        self.grid = grid
        # degrees in, degrees out; vgridshift adds multiplier * N to the height (MSL -> ellipsoid)
        self._t: Any = Transformer.from_pipeline(
            "+proj=pipeline +step +proj=unitconvert +xy_in=deg +xy_out=rad "
            f"+step +proj=vgridshift +grids={grid} +multiplier=1 +step +proj=unitconvert +xy_in=rad +xy_out=deg"
        )

    def undulation_m(self, lat_deg: float, lon_deg: float) -> float:
        return self.ellipsoid_height_m(lat_deg, lon_deg, 0.0)

    def ellipsoid_height_m(self, lat_deg: float, lon_deg: float, msl_m: float) -> float:
        h = float(self._t.transform(lon_deg, lat_deg, msl_m)[2])
        if not math.isfinite(h):  # outside the grid or not a position: PROJ gives inf
            raise ValueError(f"no geoid undulation at {lat_deg:g}, {lon_deg:g}")
        return h


def find_grid() -> Path | None:
    """The EGM96 grid in PROJ's data directories ($PROJ_DATA, $PROJ_LIB, pyproj's, the system's)."""
    dirs = [os.environ.get("PROJ_DATA", ""), os.environ.get("PROJ_LIB", "")]
    try:
        from pyproj.datadir import get_data_dir

        dirs += get_data_dir().split(os.pathsep)
    except Exception:  # pyproj missing or without a data directory: the system's may still have it
        pass
    for d in [*dirs, *SEARCH_DIRS]:
        for name in GRID_NAMES:
            if d and (Path(d) / name).is_file():
                return Path(d) / name
    return None


_default: list[Geoid | None] = []  # [] not looked for yet; [None] looked for, missing (said once)


def default() -> Geoid | None:
    """The machine's EGM96 geoid, found once; None (with one warning) without pyproj or the grid."""
    if not _default:
        _default.append(_load())
    return _default[0]


def _load() -> Geoid | None:
    try:
        import pyproj  # noqa: F401 - the geoid's one dependency
    except ImportError:
        log.warning("no geoid model (pyproj is not installed: pip install pyproj): ellipsoid heights unknown")
        return None
    grid = find_grid()
    if grid is None:
        log.warning("no EGM96 geoid grid (%s; Debian: apt-get install proj-data) in PROJ's data directories: "
                    "ellipsoid heights unknown", " or ".join(GRID_NAMES))  # fmt: skip
        return None
    try:
        return Geoid(grid)
    except Exception as exc:  # a damaged file, an old PROJ: the same as none, said once
        log.warning("the EGM96 geoid grid %s cannot be used (%s): ellipsoid heights unknown", grid, exc)
        return None


def ellipsoid_height(lat_deg: float, lon_deg: float, msl_m: float) -> float | None:
    """Height above the WGS84 ellipsoid of a point `msl_m` above mean sea level; None unknown."""
    g = default()
    if g is None or not all(math.isfinite(v) for v in (lat_deg, lon_deg, msl_m)):
        return None
    try:
        return g.ellipsoid_height_m(lat_deg, lon_deg, msl_m)
    except ValueError:
        return None
