"""One place per model: the RTSP URL the simulator serves, the URI the bridge announces in
VIDEO_STREAM_INFORMATION and the SDK's `cam.video_url()` are the same URL, read from the model
profile, and a real RTSP client (Debian's ffprobe) opens it."""

from __future__ import annotations

import asyncio
import json
import shutil
import socket
from urllib.parse import urlsplit

import pytest
from pymavlink.dialects.v20 import common as ml

import topgimbal

pytestmark = pytest.mark.external

CAMERA, THERMAL = 100, 101
FFPROBE = shutil.which("ffprobe") or "/usr/bin/ffprobe"


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return int(s.getsockname()[1])


async def _probe(url: str) -> dict:
    proc = await asyncio.create_subprocess_exec(
        FFPROBE, "-v", "error", "-rtsp_transport", "tcp", "-show_entries", "stream=codec_name,width,height",
        "-of", "json", url, stdout=asyncio.subprocess.PIPE, stderr=asyncio.subprocess.PIPE,
    )  # fmt: skip
    out, err = await asyncio.wait_for(proc.communicate(), 30)
    assert proc.returncode == 0, err.decode(errors="replace")
    return dict(json.loads(out)["streams"][0])


@pytest.mark.parametrize("model", ["SIP", "C12"])
async def test_simulator_bridge_and_sdk_give_the_same_rtsp_urls(rig_factory, model: str) -> None:
    from topgimbal.video.simvideo import SimVideo, VideoOptions

    # The first stream on a free port (the documented 554 needs root and is shared); the others
    # keep the profile's spacing, and the bridge is told the same port (`--video-port`).
    base = _free_port()
    r = await rig_factory(model, video_port=base)
    video = await SimVideo(r.sim, VideoOptions(port=base, fps=5.0)).start()
    try:
        profile = r.sim.device.model
        cam = topgimbal.AsyncClient(r.sim.url, model=model)  # no I/O: video_url() reads the profile
        lenses = [v.lens for v in profile.video]
        assert sorted(video.urls) == sorted(lenses)
        for compid, lens in ((CAMERA, "visible"), (THERMAL, "thermal")):
            served = video.urls[lens]
            info = await r.peer.request(compid, 269, "VIDEO_STREAM_INFORMATION")
            announced = info.uri
            assert info.type == ml.VIDEO_STREAM_TYPE_RTSP and info.hfov == round(profile.video_stream(lens).hfov_deg)
            sdk = cam.video_url(lens, port=urlsplit(served).port)
            assert served == announced == sdk
            # ... and it is the profile's URL at the camera's address, on the planned port
            documented = urlsplit(profile.video_stream(lens).url_for("127.0.0.1"))
            assert urlsplit(served).path == documented.path and urlsplit(served).hostname == documented.hostname
            assert urlsplit(served).port == base + (documented.port or 554) - 554
            got = await _probe(announced)
            assert got["codec_name"] == "h264" and got["width"] > 0
    finally:
        await video.stop()


async def test_bridge_refuses_a_bad_video_port() -> None:
    from topgimbal.mavlink import BridgeConfig
    from topgimbal.mavlink.bridge import BridgeConfigError

    with pytest.raises(BridgeConfigError, match=r"video_port=70000: expected 1\.\.65535"):
        BridgeConfig(url="udp://127.0.0.1:5000", model="C12", endpoints=["udpin:127.0.0.1:0"], video_port=70000).check()
