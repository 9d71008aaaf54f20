"""`--terrain DEM.tif`: CAMERA_FOV_STATUS's image centre (and CoT's, KLV's target) on a GeoTIFF DEM
rather than flat ground at home. Read once, shared by the cameras."""

from __future__ import annotations

import argparse
from dataclasses import dataclass

from .base import BridgeContext, BridgeOptions, FeatureSpec


@dataclass(frozen=True)
class TerrainConfig:
    dem_path: str


class TerrainFeature:
    name = "terrain"

    def __init__(self, config: TerrainConfig) -> None:
        self.config = config

    def attach(self, ctx: BridgeContext) -> None:
        from ...geo.dem import load_dem  # rasterio: only where a DEM is given

        terrain = load_dem(self.config.dem_path)  # DemError (a ValueError) for a file it cannot use
        for camera in ctx.cameras:
            camera.view.terrain = terrain

    async def start(self) -> None:
        pass

    async def stop(self) -> None:
        pass


def make(c: BridgeOptions) -> TerrainFeature | None:
    return TerrainFeature(TerrainConfig(c.terrain)) if c.terrain is not None else None


def check(c: BridgeOptions) -> None:
    pass  # the file is read at attach: once


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("--terrain", metavar="DEM.tif",
                   help="GeoTIFF DEM (lat/lon): CAMERA_FOV_STATUS's image centre on the terrain (default: flat at home)")  # fmt: skip


SPEC = FeatureSpec("terrain", make, check, add_arguments)
