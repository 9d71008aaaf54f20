"""Bad arguments to the video's CLI options and Python entry points get a VideoError (or an
argparse error) naming what is allowed, at once, before any socket or thread is started."""

from __future__ import annotations

import argparse
import dataclasses
import math
from typing import Any

import pytest

from topgimbal.video import cli as video_cli
from topgimbal.video.frames import frames
from topgimbal.video.lens import VideoError, plan_ports, streams_for
from topgimbal.video.simvideo import VideoOptions

pytestmark = pytest.mark.loopback

DEAD_URL = "rtsp://127.0.0.1:9/nothing"  # never opened: the arguments are refused first


def test_video_port_must_be_a_port(capsys: Any) -> None:
    p = argparse.ArgumentParser()
    video_cli.add_arguments(p)
    assert p.parse_args(["--video-port", "0"]).video_port == 0
    assert p.parse_args(["--video-port", "65535"]).video_port == 65535
    for bad in ("70000", "-1", "abc", "5e3"):
        with pytest.raises(SystemExit):
            p.parse_args(["--video-port", bad])  # before: 70000 and -1 crashed in bind() with OverflowError
        assert "0..65535" in capsys.readouterr().err


def test_planned_ports_fit_in_65535() -> None:
    visible = streams_for("C12")[0]
    specs = (visible, dataclasses.replace(visible, lens="thermal", port=visible.port + 1))
    assert plan_ports(specs, 8554) == {554: 8554, 555: 8555}
    with pytest.raises(VideoError, match=r"give 1\.\.65534"):
        plan_ports(specs, 65535)


@pytest.mark.parametrize(
    ("kwargs", "says"),
    [
        ({"format": "bogus"}, "pixel format name such as bgr24"),
        ({"format": 3}, "pixel format name"),
        ({"transport": "http"}, "tcp or udp"),
        ({"timeout_s": 0}, "above 0"),
        ({"timeout_s": -1.0}, "above 0"),
        ({"timeout_s": math.nan}, "above 0"),
        ({"timeout_s": "5"}, "above 0"),
        ({"max_frames": 0}, "from 1"),  # before: gave one picture
        ({"max_frames": -3}, "from 1"),
        ({"max_frames": 2.5}, "whole number"),
        ({"max_lag_s": -0.1}, "from 0"),  # before: dropped every picture, forever
        ({"max_lag_s": math.inf}, "from 0"),
        ({"max_lag_s": math.nan}, "from 0"),
    ],
)
def test_frames_refuses_bad_arguments_before_opening_anything(kwargs: dict[str, Any], says: str) -> None:
    with pytest.raises(VideoError, match=says):
        frames(DEAD_URL, **kwargs)  # not iterated: the check is at the call


def test_frames_takes_the_documented_formats_and_limits() -> None:
    for fmt in ("bgr24", "rgb24", "gray"):
        it = frames(DEAD_URL, format=fmt, max_frames=1, max_lag_s=0, timeout_s=0.5)
        with pytest.raises(VideoError, match="cannot open"):  # the arguments passed; the URL is dead
            next(it)


@pytest.mark.parametrize(
    ("kwargs", "says"),
    [
        ({"port": 70000}, r"port must be 0\.\.65535"),  # before: OverflowError from bind()
        ({"port": -1}, r"port must be 0\.\.65535"),
        ({"bitrate_kbps": 0}, r"bitrate must be 1\.\.100000"),  # before: 0 silently meant the default
        ({"bitrate_kbps": -500}, r"bitrate must be 1\.\.100000"),  # before: the encoder thread died
        ({"fps": 0.0}, r"fps must be within 1\.\.60"),
        ({"fps": -5.0}, r"fps must be within 1\.\.60"),
        ({"fps": math.nan}, r"fps must be within 1\.\.60"),
        ({"size": (0, 0)}, "even, 64x48..3840x2160"),
        ({"size": (1281, 720)}, "even, 64x48..3840x2160"),
    ],
)
def test_video_options_refuse_what_cannot_be_served(kwargs: dict[str, Any], says: str) -> None:
    with pytest.raises(VideoError, match=says):
        VideoOptions(**kwargs)
