"""`--video-out`: the bridge pushes each lens's stream as RTP over UDP and its camera component
advertises it (VIDEO_STREAM_TYPE_RTPUDP, udp://0.0.0.0:PORT) after the RTSP stream; QGroundControl's
GStreamer pipeline plays what arrives (the simulator's burned-in stamps, in order)."""

from __future__ import annotations

import asyncio
import shutil
import socket
from typing import Any

import numpy as np
import pytest
from pymavlink.dialects.v20 import common as ml

from topgimbal.mavlink import Bridge, BridgeConfig
from topgimbal.mavlink.bridge import BridgeConfigError
from topgimbal.video.render import decode_stamp

CAMERA, THERMAL = 100, 101
GST = shutil.which("gst-launch-1.0") or "/usr/bin/gst-launch-1.0"


def free_port(kind: int = socket.SOCK_DGRAM) -> int:
    with socket.socket(socket.AF_INET, kind) as s:
        s.bind(("127.0.0.1", 0))
        return int(s.getsockname()[1])


async def play_qgc(port: int, size: tuple[int, int], count: int) -> list[int | None]:
    """QGroundControl's pipeline on `port`; the burned-in stamps of the first `count` pictures."""
    proc = await asyncio.create_subprocess_exec(
        GST, "-q", "udpsrc", "address=127.0.0.1", f"port={port}",
        "caps=application/x-rtp,media=video,clock-rate=90000,encoding-name=H264", "!", "rtpjitterbuffer", "!",
        "rtph264depay", "!", "avdec_h264", "!", "videoconvert", "!", "video/x-raw,format=GRAY8", "!", "fdsink",
        stdout=asyncio.subprocess.PIPE, stderr=asyncio.subprocess.DEVNULL,
    )  # fmt: skip
    assert proc.stdout is not None
    w, h = size
    try:
        out = []
        for _ in range(count):
            buf = await asyncio.wait_for(proc.stdout.readexactly(w * h), 60)
            out.append(decode_stamp(np.frombuffer(buf, np.uint8).reshape(h, w)))
        return out
    finally:
        proc.kill()
        await proc.wait()


async def test_each_lens_is_pushed_and_advertised_next_to_its_rtsp_stream(rig_factory: Any) -> None:
    from topgimbal.video.simvideo import SimVideo, VideoOptions

    base = free_port(socket.SOCK_STREAM)
    vis, th = free_port(), free_port()
    r = await rig_factory("C12", video_port=base,
                          video_out=[f"udp://127.0.0.1:{vis}", f"thermal=udp://127.0.0.1:{th}"])  # fmt: skip
    video = await SimVideo(r.sim, VideoOptions(port=base, fps=10.0)).start()
    try:
        for compid, lens, port in ((CAMERA, "visible", vis), (THERMAL, "thermal", th)):
            rtsp = await r.peer.request(compid, 269, "VIDEO_STREAM_INFORMATION", param2=1)
            assert rtsp.type == ml.VIDEO_STREAM_TYPE_RTSP and rtsp.uri == video.urls[lens] and rtsp.count == 2
            udp = await r.peer.request(compid, 269, "VIDEO_STREAM_INFORMATION", param2=2)
            assert udp.type == ml.VIDEO_STREAM_TYPE_RTPUDP and udp.uri == f"udp://0.0.0.0:{port}"
            assert udp.encoding == rtsp.encoding and udp.hfov == rtsp.hfov
        stamps = await play_qgc(vis, (1280, 720), 5)
        assert None not in stamps and stamps == sorted(stamps)  # type: ignore[type-var]
        stamps = await play_qgc(th, (640, 512), 5)
        assert None not in stamps and stamps == sorted(stamps)  # type: ignore[type-var]
        assert {p.name: p.stats.send_errors for p in r.bridge.video_pushes} == {"visible": 0, "thermal": 0}
    finally:
        await video.stop()


@pytest.mark.parametrize(
    ("video_out", "extra", "why"),
    [
        (["udp://127.0.0.1"], {}, "udp://HOST:PORT"),
        (["zoom=udp://127.0.0.1:5600"], {}, "the lens is one of visible, thermal"),
        (["udp://127.0.0.1:5600", "visible=udp://127.0.0.1:5601"], {}, "given twice"),
        (["udp://127.0.0.1:5600"], {"camera_compid": None}, "needs the camera components"),
        (["thermal=udp://127.0.0.1:5600"], {"thermal": False}, "no thermal camera"),
    ],
)
def test_what_cannot_be_pushed_is_refused(video_out: list[str], extra: dict[str, Any], why: str) -> None:
    config = BridgeConfig(url="udp://127.0.0.1:9", model="C12", endpoints=["udpin:127.0.0.1:0"],
                          video_out=video_out, **extra)  # fmt: skip
    with pytest.raises(BridgeConfigError, match=why):
        Bridge(config)
