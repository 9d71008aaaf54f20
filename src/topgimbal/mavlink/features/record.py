"""`--record DIR`: the first camera's video as MPEG-TS with a MISB ST 0601 KLV stream
(outputs/klv_record.py writes it; this feeds it the camera view's KLV values)."""

from __future__ import annotations

import argparse
from dataclasses import dataclass
from typing import TYPE_CHECKING

from .base import BridgeContext, BridgeOptions, FeatureConfigError, FeatureSpec

if TYPE_CHECKING:  # loaded when a bridge is made: the flags alone keep `topgimbal --help` light
    from ...outputs.klv_record import Recorder


@dataclass(frozen=True)
class RecordConfig:
    directory: str


class RecordFeature:
    name = "record"

    def __init__(self, config: RecordConfig) -> None:
        self.config = config
        self.recorder: Recorder | None = None

    def attach(self, ctx: BridgeContext) -> None:
        from ...outputs.klv_record import Recorder

        if not ctx.cameras or not ctx.cameras[0].video_urls:
            raise FeatureConfigError("record needs the camera's video stream (a model with one, or video_urls)")
        camera = ctx.cameras[0]
        self.recorder = Recorder(camera.video_urls[0], self.config.directory, camera.view.klv_values)

    async def start(self) -> None:
        if self.recorder is not None:
            self.recorder.start()

    async def stop(self) -> None:
        import asyncio

        if self.recorder is not None:  # its thread finishes the file it writes (a few ms)
            await asyncio.to_thread(self.recorder.close)


def make(c: BridgeOptions) -> RecordFeature | None:
    return RecordFeature(RecordConfig(c.record)) if c.record is not None else None


def check(c: BridgeOptions) -> None:
    from ...outputs.klv_record import check_directory

    if c.record is not None:  # made and written to now (RecordDirError, a ValueError: exit 2)
        check_directory(c.record)


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("--record", metavar="DIR",
                   help="record the camera's video into DIR as MPEG-TS with MISB ST 0601 KLV metadata (no re-encoding)")  # fmt: skip


SPEC = FeatureSpec("record", make, check, add_arguments)
