"""Geolocation: where the camera looks, on terrain, laser range or flat ground. Pure (no I/O) but
for `dem.load_dem`, which reads a GeoTIFF with rasterio (the `geo` extra), imported when called."""

from __future__ import annotations

from .frames import Attitude, Geodetic, LocalFrame, Pointing
from .locate import CORNERS, Fix, Uncertainty, View, footprint, locate, ray, with_zoom
from .terrain import GridTerrain, Terrain

__all__ = [
    "CORNERS",
    "Attitude",
    "Fix",
    "Geodetic",
    "GridTerrain",
    "LocalFrame",
    "Pointing",
    "Terrain",
    "Uncertainty",
    "View",
    "footprint",
    "locate",
    "ray",
    "with_zoom",
]
