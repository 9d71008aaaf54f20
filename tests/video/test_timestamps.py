"""The simulated streams' time stamps as FFmpeg reads them (issue 35.6: ffmpeg reported non-monotonic
DTS on the thermal stream). Every picture's RTP time is its capture time, strictly increasing; what
FFmpeg (5.1 in Debian and the 8.x in PyAV's wheel) reports is that the first picture it parses from
any RTP H.264 source has no time stamp (its parser is never given a byte position by the RTSP/RTP
demuxers, so it cannot attach the first packet's time to the first frame; FFmpeg's own RTP sender
shows the same), and `-c copy` then numbers that picture 0 like the next one. docs/errata.md."""

from __future__ import annotations

import itertools
import subprocess
from collections.abc import Iterator

import pytest

from .conftest import FFPROBE, LiveSim

pytestmark = [pytest.mark.external, pytest.mark.integration]


@pytest.fixture(scope="module")
def sim() -> Iterator[LiveSim]:
    with LiveSim("C12", fps=15.0) as live:
        yield live


def packets(url: str, seconds: float = 2.0) -> list[tuple[int | None, int | None, bool]]:
    out = subprocess.run(
        [FFPROBE, "-v", "error", "-rtsp_transport", "tcp", "-read_intervals", f"%+{seconds}",
         "-show_entries", "packet=pts,dts,flags", "-of", "csv=p=0", url],
        capture_output=True, text=True, timeout=60, check=True,
    ).stdout  # fmt: skip
    rows = []
    for line in out.splitlines():
        pts, dts, flags = ([*line.split(","), "", "", ""])[:3]
        rows.append((int(pts) if pts.isdigit() else None, int(dts) if dts.isdigit() else None, "K" in flags))
    return rows


@pytest.mark.parametrize("lens", ["visible", "thermal"])
def test_every_picture_after_the_first_has_strictly_increasing_time_stamps(sim: LiveSim, lens: str) -> None:
    rows = packets(sim.video.urls[lens])
    assert len(rows) >= 5 and rows[0][2], rows[:3]  # a receiver starts at a keyframe
    timed = [(p, d) for p, d, _ in rows[1:]]
    assert all(p is not None and p == d for p, d in timed), timed  # no B-frames: decode order is display order
    stamps = [p for p, _ in timed if p is not None]
    steps = [b - a for a, b in itertools.pairwise(stamps)]
    assert min(steps) > 0, steps  # strictly monotonic: never a repeated or backward time
    # ... and the first keyframe itself has one when FFmpeg reports it (a later FFmpeg may)
    if rows[0][0] is not None:
        assert rows[0][0] < stamps[0]
