"""RTP push (video/rtp_push.py, `topgimbal video relay`): the simulator's stream re-sent as RTP
over UDP on loopback, played by QGroundControl's GStreamer pipeline joining late and by ffmpeg
with an SDP file; the burned-in time stamps prove the pictures are the camera's, live and whole."""

from __future__ import annotations

import os
import shutil
import socket
import subprocess
import sys
import threading
from collections.abc import Callable, Iterator
from pathlib import Path

import numpy as np
import pytest

from topgimbal.clock import wall_time
from topgimbal.video.encode import Encoder
from topgimbal.video.lens import VideoError
from topgimbal.video.render import decode_stamp
from topgimbal.video.rtp import nal_type, split_nals
from topgimbal.video.rtp_push import ParamSetInserter, RtpPush, advertised_uri, parse_udp_target
from waiting import until_blocking

from .conftest import FFMPEG, LiveSim

pytestmark = [pytest.mark.external, pytest.mark.integration]
GST = shutil.which("gst-launch-1.0") or "/usr/bin/gst-launch-1.0"
SRC = str(Path(__file__).resolve().parents[2] / "src")


def free_udp_port() -> int:
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as s:
        s.bind(("127.0.0.1", 0))
        return int(s.getsockname()[1])


def qgc_pipeline(port: int, codec: str = "H264") -> list[str]:
    """QGroundControl's UDP pipeline (udpsrc ! application/x-rtp ! rtpjitterbuffer ! depay ! decode),
    ending in raw grey pictures on stdout instead of its video sink."""
    low = codec.lower()
    return [GST, "-q", "udpsrc", "address=127.0.0.1", f"port={port}",
            f"caps=application/x-rtp,media=video,clock-rate=90000,encoding-name={codec}",
            "!", "rtpjitterbuffer", "!", f"rtp{low}depay", "!", f"avdec_{low}",
            "!", "videoconvert", "!", "video/x-raw,format=GRAY8", "!", "fdsink", "fd=1"]  # fmt: skip


PICTURES_WITHIN_S = 120.0  # GStreamer's pictures: a bound on a hang (the pipeline is killed then)


def read_pictures(proc: subprocess.Popen[bytes], size: tuple[int, int], count: int) -> list[np.ndarray]:
    w, h = size
    assert proc.stdout is not None
    out = []
    watchdog = threading.Timer(PICTURES_WITHIN_S, proc.kill)  # a read that blocks for good ends here
    watchdog.start()
    try:
        for _ in range(count):
            buf = proc.stdout.read(w * h)
            killed = "" if watchdog.is_alive() else f", killed after {PICTURES_WITHIN_S:g} s"
            assert buf is not None and len(buf) == w * h, (
                f"the pipeline stopped before giving every picture ({len(out)} of {count}{killed})"
            )
            out.append(np.frombuffer(buf, np.uint8).reshape(h, w))
    finally:
        watchdog.cancel()
    return out


@pytest.fixture
def sim() -> Iterator[LiveSim]:
    with LiveSim("C12", fps=15.0) as live:
        yield live


def wait_for(cond: Callable[[], bool], timeout_s: float = 30.0) -> None:
    until_blocking("the push's keyframes", cond, bound_s=timeout_s)  # a bound on a hang (tests/waiting.py)


# -- pure parts -------------------------------------------------------------------------------------


def test_udp_targets_are_checked() -> None:
    assert parse_udp_target("udp://127.0.0.1:5600") == ("127.0.0.1", 5600)
    assert parse_udp_target("udp://[::1]:5600") == ("::1", 5600)
    for bad in ("udp://127.0.0.1", "tcp://127.0.0.1:5600", "udp://127.0.0.1:0", "udp://127.0.0.1:70000",
                "udp://:5600", "udp://127.0.0.1:5600/x", "127.0.0.1:5600"):  # fmt: skip
        with pytest.raises(VideoError, match="udp://HOST:PORT"):
            parse_udp_target(bad)
    assert advertised_uri(5600) == "udp://0.0.0.0:5600"


def _units_without_headers(codec: str) -> tuple[bytes, list[bytes]]:
    """Access units from an encoder that sends its parameter sets only once, in the extradata (as
    cameras with global headers do): the case where a late UDP joiner never decodes."""
    import av

    enc = Encoder(codec, 64, 48, 10.0, gop=3)
    ctx = enc._ctx
    params = b"".join(b"\x00\x00\x00\x01" + n for n in split_nals(b"".join(
        bytes(p) for p in ctx.encode(av.VideoFrame.from_ndarray(np.zeros((48, 64, 3), np.uint8), format="rgb24")))))  # fmt: skip
    units = []
    for i in range(1, 7):
        frame = av.VideoFrame.from_ndarray(np.full((48, 64, 3), i * 20, np.uint8), format="rgb24")
        frame = frame.reformat(format="yuv420p")
        frame.pts = i * 9000
        units += [bytes(p) for p in ctx.encode(frame)]
    return params, units


@pytest.mark.parametrize("codec", ["h264", "h265"])
def test_parameter_sets_go_before_every_keyframe_that_lacks_them(codec: str) -> None:
    first, units = _units_without_headers(codec)
    names = ("vps", "sps", "pps") if codec == "h265" else ("sps", "pps")
    param_types = {32, 33, 34} if codec == "h265" else {7, 8}
    key_types = set(range(16, 22)) if codec == "h265" else {5}
    stripped = [b"".join(b"\x00\x00\x00\x01" + n for n in split_nals(u) if nal_type(codec, n) not in param_types)
                for u in units]  # fmt: skip
    ins = ParamSetInserter(codec, extradata=first)
    assert set(ins.params) == set(names)
    keyframes = 0
    for unit in stripped:
        sent = ins.nals(unit)
        types = [nal_type(codec, n) for n in sent]
        if key_types & set(types):
            keyframes += 1
            assert [nal_type(codec, n) for n in sent[: len(names)]] == sorted(param_types)
            assert sent[len(names) :] == split_nals(unit)
        else:
            assert sent == split_nals(unit)  # other pictures go as they are
    assert keyframes == 2 and ins.inserted == 2
    # a keyframe that carries its own parameter sets gets no second copy
    with_own = next(u for u in units if key_types & {nal_type(codec, n) for n in split_nals(u)})
    assert ins.nals(with_own) == split_nals(with_own)


# -- the simulator's stream, pushed and played -------------------------------------------------------


def test_qgc_pipeline_joining_late_decodes_the_live_picture(sim: LiveSim) -> None:
    port = free_udp_port()
    push = RtpPush(sim.video.urls["visible"], f"udp://127.0.0.1:{port}", name="visible").start()
    try:
        wait_for(lambda: push.stats.keyframes >= 2)  # the receiver joins well after the stream started
        joined_ms = wall_time() * 1000
        keyframes_at_join = push.stats.keyframes
        proc = subprocess.Popen(qgc_pipeline(port), stdout=subprocess.PIPE, stderr=subprocess.PIPE)
        try:
            pictures = read_pictures(proc, (1280, 720), 20)
        finally:
            proc.kill()
            proc.communicate()
    finally:
        push.stop()
    stamps = [decode_stamp(p) for p in pictures]
    ms = [s for s in stamps if s is not None]
    assert len(ms) == len(stamps), "a picture came out damaged (decoded without its references)"
    assert ms == sorted(ms) and len(set(ms)) == len(ms)  # in order, no repeats
    assert ms[0] >= joined_ms - 100  # live pictures, not a backlog
    # the first picture is the first keyframe after joining: the parameter sets came with it
    assert push.stats.keyframes > keyframes_at_join
    assert push.stats.send_errors == 0


def test_video_relay_command_plays_in_ffmpeg_with_its_sdp_file(sim: LiveSim, tmp_path: Path) -> None:
    port = free_udp_port()
    sdp = tmp_path / "thermal.sdp"
    env = {**os.environ, "PYTHONPATH": SRC}
    relay = subprocess.Popen(
        [sys.executable, "-m", "topgimbal.cli.main", "video", "relay", "--from", sim.video.urls["thermal"],
         "--to", f"udp://127.0.0.1:{port}", "--sdp", str(sdp), "--seconds", "60"],
        stdout=subprocess.PIPE, stderr=subprocess.PIPE, env=env, text=True,
    )  # fmt: skip
    try:
        assert relay.stdout is not None
        assert "-> udp://127.0.0.1:" in relay.stdout.readline()
        assert relay.stdout.readline().strip() == f"video relay: SDP in {sdp}"
        text = sdp.read_text()
        assert f"m=video {port} RTP/AVP 96" in text and "sprop-parameter-sets=" in text
        w, h = 640, 512
        out = subprocess.run(
            [FFMPEG, "-v", "error", "-protocol_whitelist", "file,udp,rtp", "-i", str(sdp), "-frames:v", "10",
             "-f", "rawvideo", "-pix_fmt", "gray", "-"],
            capture_output=True, timeout=60, check=True,
        ).stdout  # fmt: skip
    finally:
        relay.terminate()
        _, err = relay.communicate(timeout=30)
    assert len(out) == 10 * w * h
    stamps = [decode_stamp(np.frombuffer(out[i * w * h : (i + 1) * w * h], np.uint8).reshape(h, w)) for i in range(10)]
    ms = [s for s in stamps if s is not None]
    assert len(ms) == 10 and ms == sorted(ms)
    assert "pictures" in err and "packets sent" in err


def test_video_relay_refuses_what_it_cannot_use() -> None:
    env = {**os.environ, "PYTHONPATH": SRC}
    for args, why in (
        (["--from", "http://127.0.0.1:1/x", "--to", "udp://127.0.0.1:5600"], "rtsp://"),
        (["--from", "rtsp://127.0.0.1:1/x", "--to", "udp://127.0.0.1"], "udp://HOST:PORT"),
    ):
        r = subprocess.run([sys.executable, "-m", "topgimbal.cli.main", "video", "relay", *args],
                           capture_output=True, text=True, env=env, timeout=60)  # fmt: skip
        assert r.returncode == 2 and why in r.stderr


def test_h265_is_pushed_as_it_is_and_plays_in_gstreamer() -> None:
    with LiveSim("SIP", fps=10.0, size=(320, 240), codec="h265") as live:
        port = free_udp_port()
        push = RtpPush(live.video.urls["visible"], f"udp://127.0.0.1:{port}", name="h265").start()
        try:
            wait_for(lambda: push.stats.keyframes >= 1)
            assert push.codec == "h265" and set(push.params) == {"vps", "sps", "pps"}
            proc = subprocess.Popen(qgc_pipeline(port, "H265"), stdout=subprocess.PIPE, stderr=subprocess.PIPE)
            try:
                pictures = read_pictures(proc, (320, 240), 5)
            finally:
                proc.kill()
                proc.communicate()
        finally:
            push.stop()
    ms = [s for s in (decode_stamp(p) for p in pictures) if s is not None]
    assert len(ms) == 5 and ms == sorted(ms)
