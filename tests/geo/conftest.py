"""A synthetic DEM with hills, 10 m cells, written with rasterio into a temporary directory."""

from __future__ import annotations

from pathlib import Path

import pytest

from topgimbal.geo.synthetic import write_dem

LAT0, LON0 = 47.0, 8.0


@pytest.fixture(scope="session")
def dem_path(tmp_path_factory: pytest.TempPathFactory) -> Path:
    return write_dem(tmp_path_factory.mktemp("dem") / "hills.tif", LAT0, LON0)
