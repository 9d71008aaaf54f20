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

pytestmark = pytest.mark.external

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


@pytest.mark.serial  # two lenses encoding H.264 in real time, two RTP pushes and their GStreamer readers:
# beside six workers and two busy loops the pumps starved until the 600 s timeout (make flake, HOG=2)
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


def test_camera_options_are_read_per_camera() -> None:
    from topgimbal.cli.mavlink_multi import camera_with_options

    c = camera_with_options("left=udp://127.0.0.2:5000,C12,video-port=8554,video-out=udp://127.0.0.1:5600,"
                            "video-out=thermal=udp://127.0.0.1:5601,video-url=rtsp://127.0.0.2:1/a")  # fmt: skip
    assert (c.name, c.url, c.model) == ("left", "udp://127.0.0.2:5000", "C12")
    assert c.options == {"video_port": 8554, "video_urls": ["rtsp://127.0.0.2:1/a"],
                         "video_out": ["udp://127.0.0.1:5600", "thermal=udp://127.0.0.1:5601"]}  # fmt: skip
    assert camera_with_options("b=udp://127.0.0.1:5000,SIP").options == {}
    for bad in ("a=udp://127.0.0.1:5000,C12,video-port=0", "a=udp://127.0.0.1:5000,C12,video-port=1,video-port=2"):
        with pytest.raises(Exception, match="video-port"):
            camera_with_options(bad)


@pytest.mark.serial  # two simulated cameras each encoding H.264 in real time, and two RTP pushes:
# beside six workers and two busy loops it ran past the 180 s bound (a pump starved, not a hang)
async def test_two_cameras_on_one_bridge_each_advertise_and_play_their_own_video() -> None:
    from topgimbal.cli.mavlink_multi import camera_with_options
    from topgimbal.mavlink.multi import MultiBridge
    from topgimbal.sim import Simulator
    from topgimbal.video.simvideo import SimVideo, VideoOptions

    from .conftest import Peer

    # Two cameras on their own loopback addresses, on the same RTSP port (as two real cameras
    # on their documented port), each picture a size of its own so a mix-up cannot decode.
    sizes = {"a": (320, 240), "b": (480, 270)}
    sims = {n: Simulator("C12") for n in sizes}
    hosts = {"a": "127.0.0.2", "b": "127.0.0.3"}
    rtsp_port = free_port(socket.SOCK_STREAM)
    out = {n: free_port() for n in sizes}
    videos = {}
    for n, sim in sims.items():
        await sim.start(udp=[(hosts[n], 0)])
        videos[n] = await SimVideo(sim, VideoOptions(host=hosts[n], port=rtsp_port, fps=5.0, size=sizes[n])).start()
    specs = [camera_with_options(f"{n}={sims[n].url},C12,video-port={rtsp_port},video-out=udp://127.0.0.1:{out[n]}")
             for n in sizes]  # fmt: skip
    multi = MultiBridge([(s.name, s.url, s.model) for s in specs], endpoints=["udpin:127.0.0.1:0"],
                        per_camera=[s.options for s in specs], silence_s=0.6, timeout_s=0.3, retries=1)  # fmt: skip
    await multi.start()
    peer = await Peer().connect(multi.addresses[0][1])  # type: ignore[index]
    try:
        for n, compid in (("a", 100), ("b", 102)):  # each C12 takes a visible and a thermal camera id
            rtsp = await peer.request(compid, 269, "VIDEO_STREAM_INFORMATION", param2=1)
            assert rtsp.uri == videos[n].urls["visible"] and rtsp.uri.startswith(f"rtsp://{hosts[n]}:{rtsp_port}/")
            udp = await peer.request(compid, 269, "VIDEO_STREAM_INFORMATION", param2=2)
            assert udp.type == ml.VIDEO_STREAM_TYPE_RTPUDP and udp.uri == f"udp://0.0.0.0:{out[n]}"
            stamps = await play_qgc(out[n], sizes[n], 4)
            assert None not in stamps and stamps == sorted(stamps)  # type: ignore[type-var]
    finally:
        peer.close()
        await multi.close()
        for n, sim in sims.items():
            await videos[n].stop()
            await sim.stop()


async def _cli(*args: str) -> tuple[int, str]:
    import sys

    proc = await asyncio.create_subprocess_exec(
        sys.executable, "-m", "topgimbal.cli.main", "mavlink", *args,
        stdout=asyncio.subprocess.PIPE, stderr=asyncio.subprocess.PIPE,
    )  # fmt: skip
    _, err = await asyncio.wait_for(proc.communicate(), 60)
    return proc.returncode or 0, err.decode()


@pytest.mark.parametrize(
    "option",
    [["--compid", "171"], ["--camera-compid", "102"], ["--video-port", "8554"], ["--video-url", "rtsp://127.0.0.1:1/a"],
     ["--video-out", "udp://127.0.0.1:5600"], ["--media-url", "http://127.0.0.1:1/"]],
)  # fmt: skip
async def test_one_camera_options_are_refused_with_several_cameras(option: list[str]) -> None:
    code, err = await _cli("--mavlink", "udpin:127.0.0.1:0", "--camera", "a=udp://127.0.0.1:9,C12",
                           "--camera", "b=udp://127.0.0.1:10,C12", *option, "--seconds", "0")  # fmt: skip
    assert code == 2 and f"with --camera, {option[0]}" in err and "Traceback" not in err
