"""The names the simulated camera gives its files (media.py says why), in a module of its own so
the MAVLink bridge can name a photo's file without loading the renderer."""

from __future__ import annotations

import re

MEDIA_NAME = re.compile(r"^(IMG_\d{4,}(_T)?\.jpg|snap_[01]_\d+\.jpeg|stream_0_\d+\.mp4|VID_\d{4,}\.mp4)$")


def photo_names(dialect: str, index: int, lenses: list[str]) -> dict[str, str]:
    if dialect == "topotek":
        return {lens: f"snap_{int(lens == 'thermal')}_{index}.jpeg" for lens in lenses}
    return {lens: f"IMG_{index:04d}{'_T' if lens == 'thermal' else ''}.jpg" for lens in lenses}


def recording_name(dialect: str, index: int) -> str:
    return f"stream_0_{index}.mp4" if dialect == "topotek" else f"VID_{index:04d}.mp4"
