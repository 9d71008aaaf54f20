"""`--sightings FILE`: a JSON Lines log of where the first camera looks, once a second
(outputs/sightings_log.py writes it; this attaches it to the bridge's sighting port). A feature
without a BridgeConfig field: its option lives in `BridgeConfig.features["sightings"]`."""

from __future__ import annotations

import argparse
from collections.abc import Callable
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

from .base import BridgeContext, BridgeOptions, FeatureSpec, SightingOutput, option

if TYPE_CHECKING:  # loaded when a bridge is made: the flags alone keep `topgimbal --help` light
    from ...outputs.sighting import Sighting
    from ...outputs.sightings_log import SightingsLog


@dataclass(frozen=True)
class SightingsConfig:
    path: str


class SightingsFeature(SightingOutput):
    name = "sightings"

    def __init__(self, config: SightingsConfig) -> None:
        super().__init__()
        self.config = config

    def build(self, ctx: BridgeContext, source: Callable[[], Sighting | None]) -> SightingsLog:
        from ...outputs.sightings_log import SightingsLog

        return SightingsLog(self.config.path, source)  # closes its file when its run() ends


def make(c: BridgeOptions) -> SightingsFeature | None:
    path = option(c, "sightings")
    return SightingsFeature(SightingsConfig(path)) if path is not None else None


def check(c: BridgeOptions) -> None:
    from ...outputs.sightings_log import check_path

    path = option(c, "sightings")
    if path is not None:
        if not isinstance(path, str) or not path:
            raise ValueError(f"sightings {path!r}: expected a file path")
        check_path(path)  # SightingsLogError (a ValueError: exit 2); nothing is created


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("--sightings", metavar="FILE",
                   help="append where the camera looks to FILE once a second, as JSON Lines (the vehicle, the "
                   "optical axis, the field of view, the target and the corners; at most 1 GiB)")  # fmt: skip


def from_args(args: Any) -> str | None:
    value: str | None = getattr(args, "sightings", None)
    return value


SPEC = FeatureSpec("sightings", make, check, add_arguments, from_args)
