"""Fixtures for the video tests: a simulator with its video in a background event loop, and a
reader that grabs decoded pictures with Debian's ffmpeg (an independent RTSP client)."""

from __future__ import annotations

import asyncio
import shutil
import subprocess
import threading
from collections.abc import Coroutine, Iterator
from typing import Any, TypeVar

import numpy as np
import pytest

from console.conftest import artifacts, browser  # noqa: F401  (the console tests' chromium fixtures)
from topgimbal.sim import Simulator
from topgimbal.video.simvideo import SimVideo, VideoOptions

T = TypeVar("T")
FFMPEG = shutil.which("ffmpeg") or "/usr/bin/ffmpeg"
FFPROBE = shutil.which("ffprobe") or "/usr/bin/ffprobe"
STREAMS_READY_S = 60.0  # a bound on a hang: the first keyframe of every stream


class LiveSim:
    """Simulator + SimVideo on 127.0.0.1 (free ports), in their own thread and loop."""

    def __init__(self, model: str, **video: Any) -> None:
        self.loop = asyncio.new_event_loop()
        self.thread = threading.Thread(target=self.loop.run_forever, daemon=True)
        self.sim = Simulator(model)
        self.video = SimVideo(self.sim, VideoOptions(port=0, **video))

    def run(self, coro: Coroutine[Any, Any, T], timeout: float = 30.0) -> T:
        return asyncio.run_coroutine_threadsafe(coro, self.loop).result(timeout)

    def call(self, fn: Any) -> Any:
        async def wrap() -> Any:
            return fn()

        return self.run(wrap())

    def __enter__(self) -> LiveSim:
        self.thread.start()
        self.run(self.sim.start(udp=[("127.0.0.1", 0)]))
        self.run(self.video.start())
        self.run(self._first_pictures(), timeout=STREAMS_READY_S + 5)
        return self

    async def _first_pictures(self) -> None:
        """Every stream's first keyframe encoded (its parameter sets known), as a camera that has
        been on for a while: a DESCRIBE otherwise waits for the encoder's start, which on a loaded
        machine outlasted the server's DESCRIBE_WAIT_S (a 503, seen beside two busy loops). The
        server's own wait is tested in test_rtsp_*.py."""
        for stream in self.video.streams.values():
            stream.want_keyframe()
        for lens, stream in self.video.streams.items():
            try:
                await asyncio.wait_for(stream.ready.wait(), STREAMS_READY_S)
            except asyncio.TimeoutError:
                raise AssertionError(f"the {lens} stream had no keyframe within {STREAMS_READY_S:g} s") from None

    def __exit__(self, *exc: object) -> None:
        self.run(self.video.stop())
        self.run(self.sim.stop())
        self.loop.call_soon_threadsafe(self.loop.stop)
        self.thread.join(5)
        self.loop.close()

    @property
    def url(self) -> str:
        return self.sim.url


def grab(
    url: str, size: tuple[int, int], frames: int = 1, transport: str = "tcp", *, every_picture: bool = False
) -> list[np.ndarray]:
    """Decoded RGB pictures read from an RTSP URL by ffmpeg. `every_picture`: each decoded picture
    once (`-fps_mode passthrough`); by default ffmpeg's raw output keeps a constant rate and repeats
    a picture to fill a gap in the stream (a loaded machine: 20 pictures held 6 distinct ones)."""
    w, h = size
    mode = ["-fps_mode", "passthrough"] if every_picture else []
    out = subprocess.run(
        [
            FFMPEG,
            "-v",
            "error",
            "-rtsp_transport",
            transport,
            "-i",
            url,
            *mode,
            "-frames:v",
            str(frames),
            "-f",
            "rawvideo",
            "-pix_fmt",
            "rgb24",
            "-",
        ],
        capture_output=True,
        timeout=30,
        check=True,
    ).stdout
    n = w * h * 3
    assert len(out) == n * frames, f"ffmpeg gave {len(out)} bytes, expected {frames} pictures of {w}x{h}"
    return [np.frombuffer(out[i * n : (i + 1) * n], np.uint8).reshape(h, w, 3) for i in range(frames)]


@pytest.fixture
def c12() -> Iterator[LiveSim]:
    with LiveSim("C12", fps=15.0) as live:
        yield live
