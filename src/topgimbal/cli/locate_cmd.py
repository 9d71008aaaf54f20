"""`topgimbal locate`: where the camera looks, with the source of the answer and its error."""

from __future__ import annotations

import argparse
from collections.abc import Awaitable, Callable
from typing import Any

from ..errors import TopGimbalError
from .args import lat_lon_alt, number


async def _locate(cam: Any, args: argparse.Namespace) -> dict[str, object]:
    from ..client.locating import locate_now
    from ..geo import Uncertainty

    if args.position is None or args.heading is None:
        raise TopGimbalError("locate needs where the vehicle is: --position LAT,LON,ALT (MSL) and --heading DEG")
    if args.terrain is None and not args.laser and args.ground_alt is None:
        raise TopGimbalError("locate on what? give --terrain DEM.tif, --laser or --ground-alt M (flat ground)")
    fix, inputs = await locate_now(
        cam,
        terrain=args.terrain,
        laser=args.laser,
        ground_alt_m=args.ground_alt,
        position=args.position,
        heading_deg=args.heading,
        uncertainty=Uncertainty(),
        measure_range=cam.range,
    )
    if fix is None:
        why = "the ray meets nothing known"
        if args.laser and inputs.get("laser_m") is None:
            why += " (the laser reported no distance)"
        raise TopGimbalError(f"nothing located: {why}; inputs {inputs}")
    return {**fix.as_dict(), "inputs": inputs}


def register(
    sub: argparse._SubParsersAction,
    command: Callable[
        [argparse._SubParsersAction, str, Callable[[Any, argparse.Namespace], Awaitable[object]], str],
        argparse.ArgumentParser,
    ],
) -> None:
    p = command(sub, "locate", _locate, "where the camera looks: position, source (laser/terrain/flat) and error")
    p.add_argument(
        "--position", type=lat_lon_alt, metavar="LAT,LON,ALT", help="the vehicle: degrees, degrees, metres MSL"
    )
    p.add_argument("--heading", type=number(low=-360, high=360, what="a heading"), metavar="DEG",
                   help="the vehicle's heading, degrees from true north")  # fmt: skip
    p.add_argument("--terrain", metavar="DEM.tif", help="a GeoTIFF DEM in lat/lon (the geo extra: rasterio)")
    p.add_argument("--laser", action="store_true", help="measure the laser range first and use it")
    p.add_argument("--ground-alt", type=number(low=-500, high=9000, what="a ground altitude"), metavar="M",
                   help="flat ground at M metres MSL: the last resort")  # fmt: skip
