"""The simulator's RTSP streams, read by Debian's ffprobe/ffmpeg: codecs and sizes, the picture
following the gimbal and the zoom, several receivers, the CLI."""

from __future__ import annotations

import json
import subprocess
import sys
import threading
import time
from typing import Any

import numpy as np
import pytest

import topgimbal
from topgimbal.video import world
from topgimbal.video.lens import View, hfov_at, stream_for
from topgimbal.video.render import decode_stamp
from waiting import until_blocking

from .blobs import nearest, red_blobs
from .conftest import FFPROBE, LiveSim, grab

pytestmark = [pytest.mark.external, pytest.mark.integration]

# Where a landmark's bullseye is found against where the lens model puts it. The centroid of a
# ~30 px ring in an H.264 picture lands within a pixel of its centre; the picture is taken at
# most one frame after the gimbal settled (it is still), so 3 px (0.15 deg at 62 deg / 1280 px)
# separates "right place" from any real error (one landmark step is 30 deg = hundreds of px).
TOLERANCE_PX = 3.0
SIM_CLI = (sys.executable, "-m", "topgimbal.cli.main", "sim")


def probe(url: str, transport: str = "tcp", timeout_s: float = 60) -> dict:
    out = subprocess.run(
        [
            FFPROBE,
            "-v",
            "error",
            "-rtsp_transport",
            transport,
            "-show_entries",
            "stream=codec_name,width,height",
            "-of",
            "json",
            url,
        ],
        capture_output=True,
        text=True,
        timeout=timeout_s,  # a bound on a hang
    )
    assert out.returncode == 0 and out.stdout, f"ffprobe {url} ({transport}): exit {out.returncode}: {out.stderr}"
    return json.loads(out.stdout)["streams"][0]


def _codec_or_why(url: str) -> str:
    """The stream's codec, or why ffprobe could not say (for a wait that reads again). A probe
    that hangs (one caught mid-restart) is killed after 20 s and read again, not the whole wait."""
    try:
        return str(probe(url, timeout_s=20)["codec_name"])
    except AssertionError as exc:
        return str(exc)[:200]
    except subprocess.TimeoutExpired:
        return "ffprobe hung for 20 s"


def test_ffprobe_reads_the_c12s_visible_and_thermal_streams(c12: LiveSim) -> None:
    urls = c12.video.urls
    assert urls["visible"].endswith("/stream=1") and urls["thermal"].endswith("/stream=2")
    assert probe(urls["visible"], "udp") == {"codec_name": "h264", "width": 1280, "height": 720}
    assert probe(urls["thermal"], "tcp") == {"codec_name": "h264", "width": 640, "height": 512}


def _predicted(live: LiveSim, number: int) -> tuple[float, float]:
    yaw, pitch, roll = live.call(lambda: (live.sim.device.sync(), live.sim.gimbal.earth())[1])
    zoom = live.call(lambda: live.sim.camera.zoom_x)
    spec = stream_for("C12", "visible")
    view = View(yaw, pitch, roll, hfov_at(spec.hfov_deg, zoom), *spec.size)
    m = world.landmark(number)
    p = view.project(m.az_deg, m.el_deg)
    assert p is not None
    return p


def test_a_landmark_moves_as_the_gimbal_turns_and_zooms(c12: LiveSim) -> None:
    url = c12.video.urls["visible"]
    with topgimbal.Gimbal(c12.url, model="C12") as cam:
        cam.point(0, 0, tolerance_deg=0.05)
        (pic,) = grab(url, (1280, 720))
        x0, y0 = _predicted(c12, 1)
        assert abs(x0 - 640) < 2 and abs(y0 - 360) < 2  # landmark 1 is due north, on the horizon
        bx, by, err = nearest(red_blobs(pic), x0, y0)
        assert err < TOLERANCE_PX, (bx, by, x0, y0)

        cam.point(20, -5, tolerance_deg=0.05)  # landmark 2 (bearing 30) is now 10 deg right, 5 up
        (pic,) = grab(url, (1280, 720))
        x1, y1 = _predicted(c12, 2)
        assert x1 - 640 == pytest.approx(640 / 0.6009 * 0.1763 / 0.9962, rel=0.05)  # f tan(10) / cos-ish
        bx, by, err = nearest(red_blobs(pic), x1, y1)
        assert err < TOLERANCE_PX, (bx, by, x1, y1)

        cam.digital_zoom(2)  # twice the focal length: the offset from the centre doubles
        time.sleep(0.3)
        (pic,) = grab(url, (1280, 720))
        x2, y2 = _predicted(c12, 2)
        assert x2 - 640 == pytest.approx(2 * (x1 - 640), rel=0.01)
        bx, by, err = nearest(red_blobs(pic), x2, y2)
        assert err < TOLERANCE_PX, (bx, by, x2, y2)
        # ... and nothing is left where it was before the zoom.
        assert nearest(red_blobs(pic), x1, y1)[2] > 20


def test_two_receivers_get_the_same_pictures(c12: LiveSim) -> None:
    url = c12.video.urls["thermal"]
    results: dict[str, list] = {}

    def read(name: str, transport: str) -> None:
        # 3 s of pictures each, every one once: the two sessions may start up to a second or two
        # apart on a loaded machine (RTSP over TCP and over UDP set up differently), and at a
        # constant output rate ffmpeg repeated pictures to fill gaps (a run beside two busy loops:
        # 20 pictures, 6 distinct, one in common)
        results[name] = grab(url, (640, 512), frames=45, transport=transport, every_picture=True)

    threads = [threading.Thread(target=read, args=(n, t)) for n, t in (("a", "tcp"), ("b", "udp"))]
    for t in threads:
        t.start()
    for t in threads:
        t.join(60)
    stamps = {n: {decode_stamp(p) for p in pics} for n, pics in results.items()}
    assert None not in stamps["a"] | stamps["b"]
    # Same encoder, same pictures: the burned-in capture times of the two receivers coincide.
    assert len(stamps["a"] & stamps["b"]) >= 5


def test_sim_cli_serves_video_on_free_ports_with_h265_when_told() -> None:
    proc = subprocess.Popen(
        [
            *SIM_CLI,
            "--model",
            "SIP",
            "--udp",
            "127.0.0.1:0",
            "--video",
            "--video-port",
            "0",
            "--video-fps",
            "10",
            "--video-size",
            "320x240",
            "--video-codec",
            "h265",
        ],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
    )
    try:
        assert proc.stdout is not None
        lines = [proc.stdout.readline().strip() for _ in range(3)]
        rtsp = [u for u in lines if u.startswith("rtsp://127.0.0.1:")]
        assert [u.rsplit("/", 1)[1] for u in rtsp] == ["stream=0", "stream=1"], lines
        assert probe(rtsp[0]) == {"codec_name": "hevc", "width": 320, "height": 240}
        assert probe(rtsp[1])["codec_name"] == "hevc"
    finally:
        proc.terminate()
        proc.wait(10)


def test_sim_cli_refuses_a_non_loopback_video_address() -> None:
    r = subprocess.run(
        [
            *SIM_CLI,
            "--model",
            "C12",
            "--udp",
            "127.0.0.1:0",
            "--video",
            "--video-port",
            "0",
            "--video-host",
            "0.0.0.0",
        ],
        capture_output=True,
        text=True,
        timeout=30,
    )
    assert r.returncode != 0
    assert "loopback only" in r.stderr


def test_two_simulated_cameras_share_their_ports_on_other_loopback_addresses() -> None:
    """Any address of 127.0.0.0/8 is loopback: two cameras, each on its own, on the same RTSP port."""
    import socket

    with socket.socket() as s:
        s.bind(("127.0.0.2", 0))
        port = s.getsockname()[1]
    procs = [
        subprocess.Popen([*SIM_CLI, "--model", "SIP", "--udp", f"{host}:0", "--video", "--video-port", str(port),
                          "--video-fps", "5", "--video-size", "320x240"],
                         stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
        for host in ("127.0.0.2", "127.0.0.3")
    ]  # fmt: skip
    try:
        for host, proc in zip(("127.0.0.2", "127.0.0.3"), procs, strict=True):
            assert proc.stdout is not None
            lines = [proc.stdout.readline().strip() for _ in range(3)]
            assert lines[0].startswith(f"udp://{host}:"), lines
            assert lines[1] == f"rtsp://{host}:{port}/stream=0", lines
            assert probe(lines[1]) == {"codec_name": "h264", "width": 320, "height": 240}
    finally:
        for proc in procs:
            proc.terminate()
            proc.wait(10)


def test_sdk_frames_yields_decoded_pictures_from_the_cameras_url(c12: LiveSim) -> None:
    from topgimbal.video.frames import frames

    port = int(c12.video.urls["thermal"].rsplit(":", 1)[1].split("/")[0])
    with topgimbal.Gimbal(c12.url, model="C12") as cam:
        url = cam.video_url("thermal", port=port)  # the documented path, on the simulator's free port
    assert url == c12.video.urls["thermal"]
    pictures = list(frames(url, max_frames=3))
    assert [p.shape for p in pictures] == [(512, 640, 3)] * 3
    t0 = time.time() * 1000
    stamps = [decode_stamp(p[..., ::-1]) for p in pictures]  # BGR for OpenCV; the stamp is grey anyway
    assert all(s is not None and t0 - 10_000 < s <= t0 for s in stamps)


def test_frames_says_what_is_wrong_with_a_dead_url() -> None:
    from topgimbal.video import VideoError
    from topgimbal.video.frames import frames

    with pytest.raises(VideoError, match=r"cannot open rtsp://127\.0\.0\.1:9/"):
        next(frames("rtsp://127.0.0.1:9/stream=1", timeout_s=2))


def _rtsp(sock: Any, request: str) -> str:
    sock.sendall(request.encode())
    data = b""
    while b"\r\n\r\n" not in data:
        chunk = sock.recv(4096)
        if not chunk:
            break
        data += chunk
    return data.decode(errors="replace")


def test_rtsp_server_answers_bad_input_clearly_and_bounds_receivers(c12: LiveSim, monkeypatch: Any) -> None:
    import socket

    from topgimbal.video import rtsp_connection

    url = c12.video.urls["visible"]
    port = int(url.rsplit(":", 1)[1].split("/")[0])
    with socket.create_connection(("127.0.0.1", port), timeout=10) as s:
        assert _rtsp(s, "HELLO\r\n\r\n").startswith("RTSP/1.0 400")
    with socket.create_connection(("127.0.0.1", port), timeout=10) as s:
        assert _rtsp(s, f"DESCRIBE rtsp://127.0.0.1:{port}/nope RTSP/1.0\r\nCSeq: 1\r\n\r\n").startswith("RTSP/1.0 404")
        assert "405" in _rtsp(s, f"RECORD {url} RTSP/1.0\r\nCSeq: 2\r\n\r\n").split("\r\n")[0]
    monkeypatch.setattr(rtsp_connection, "MAX_RECEIVERS", 1)
    setup = f"SETUP {url}/trackID=0 RTSP/1.0\r\nCSeq: 3\r\nTransport: RTP/AVP/TCP;unicast;interleaved=0-1\r\n\r\n"
    with (
        socket.create_connection(("127.0.0.1", port), timeout=10) as a,
        socket.create_connection(("127.0.0.1", port), timeout=10) as b,
    ):
        first = _rtsp(a, setup)
        assert first.startswith("RTSP/1.0 200") and "interleaved=0-1" in first
        session = next(
            line.split(":", 1)[1].split(";")[0].strip() for line in first.split("\r\n") if line.startswith("Session")
        )
        assert _rtsp(a, f"PLAY {url} RTSP/1.0\r\nCSeq: 4\r\nSession: {session}\r\n\r\n").startswith("RTSP/1.0 200")
        assert _rtsp(b, setup).startswith("RTSP/1.0 453")  # one receiver already plays
    # ... and the server still serves a well-behaved client.
    assert probe(url)["codec_name"] == "h264"


def test_thermal_stream_follows_the_palette_and_the_osd_setting(c12: LiveSim) -> None:
    url = c12.video.urls["thermal"]
    corner = (slice(0, 60), slice(0, 200))  # where the OSD text is
    with topgimbal.Gimbal(c12.url, model="C12") as cam:
        cam.point(30, -20, tolerance_deg=0.05)  # sim/scene.py's hot object in the centre
        cam.palette("black_hot")
        (black,) = grab(url, (640, 512))
        cam.palette("white_hot")
        (white,) = grab(url, (640, 512))
        assert black[256, 320].max() < 40 and white[256, 320].min() > 215  # hottest: black, then white
        # The ground (the commonest level) inverts too: black hot is white hot upside down.
        ground_black, ground_white = (int(np.bincount(p[..., 0].ravel()).argmax()) for p in (black, white))
        assert ground_black != ground_white and abs(ground_black + ground_white - 255) <= 3
        osd_on = white[corner].astype(int)
        cam.request("EXT", osd="off", led="off")
        (plain,) = grab(url, (640, 512))
        assert np.abs(osd_on - plain[corner]).max() > 100  # the OSD text is gone
        assert c12.call(lambda: c12.sim.settings["EXT"]["osd"]) == "off"


def test_ent_switches_the_codec_of_a_running_stream() -> None:
    import socket

    with LiveSim("SIP", fps=10.0, size=(320, 240)) as live:
        visible, thermal = live.video.urls["visible"], live.video.urls["thermal"]
        port = int(visible.rsplit(":", 1)[1].split("/")[0])
        assert probe(visible)["codec_name"] == "h264"
        with socket.create_connection(("127.0.0.1", port), timeout=10) as player:
            setup = f"SETUP {visible}/trackID=0 RTSP/1.0\r\nCSeq: 1\r\nTransport: RTP/AVP/TCP;unicast;interleaved=0-1\r\n\r\n"
            answer = _rtsp(player, setup)
            session = next(
                x.split(":", 1)[1].split(";")[0].strip() for x in answer.split("\r\n") if x.startswith("Session")
            )
            assert _rtsp(player, f"PLAY {visible} RTSP/1.0\r\nCSeq: 2\r\nSession: {session}\r\n\r\n").startswith(
                "RTSP/1.0 200"
            )
            assert player.recv(65536)  # RTP arrives
            with topgimbal.Gimbal(live.url, model="SIP") as cam:
                cam.request("ENT", stream="stream0", codec="h265")  # the main (visible) stream to H.265
            # The encoder restarts: a player of the old codec is disconnected (its RTP session cannot
            # change payload format); it reads what was in flight, then the end of the connection.
            player.settimeout(10)
            while player.recv(65536):
                pass
        assert probe(visible) == {"codec_name": "hevc", "width": 320, "height": 240}
        assert probe(thermal)["codec_name"] == "h264"  # the sub stream keeps its codec
        with topgimbal.Gimbal(live.url, model="SIP") as cam:
            cam.request("ENT", stream="stream1", codec="h265")  # the last write names stream1 only ...
        until_blocking(  # while the encoder restarts, a DESCRIBE may get 503: read again
            "the thermal stream's codec",
            lambda: _codec_or_why(thermal),
            lambda c: c == "hevc",
            bound_s=90,
            every_s=0.2,
        )
        assert probe(visible)["codec_name"] == "hevc"  # ... and stream0 keeps what it was set to


def test_a_receiver_playing_starts_the_c11s_video_output_and_its_photos_count() -> None:
    """The C11 acts on camera commands only once its video output has started: in the simulator a
    receiver playing the RTSP stream is what starts it (issue 10)."""
    with LiveSim("C11", fps=10.0, size=(320, 240)) as c11:
        assert not c11.call(lambda: c11.sim.camera.video_output)
        with topgimbal.Gimbal(c11.url, model="C11") as cam:
            cam.photo()  # acknowledged, not taken: no picture has been played yet
            assert c11.call(lambda: c11.sim.camera.photos_taken) == 0
            grab(c11.video.urls["visible"], (320, 240))
            assert c11.call(lambda: c11.sim.camera.video_output)
            cam.photo()
            assert c11.call(lambda: c11.sim.camera.photos_taken) == 1
