"""The pure parts: the lens model, stream URLs, RTP packetisation, the renderer's picture."""

from __future__ import annotations

import dataclasses
import math
from typing import Any

import numpy as np
import pytest

from topgimbal.video import VideoError, video_url
from topgimbal.video.lens import View, hfov_at, host_of, streams_for
from topgimbal.video.render import Renderer, decode_stamp
from topgimbal.video.rtp import Packetizer, parameter_sets, sdp, split_nals
from topgimbal.video.simvideo import VideoOptions, plan_ports
from topgimbal.video.snapshot import SceneState

pytestmark = pytest.mark.virtual


def _two_port_c12() -> Any:
    """A C12 whose thermal stream is on a port of its own (as public C13 probes report)."""
    from topgimbal.protocol import VideoStream, get_model

    c12 = get_model("C12")[1]
    return dataclasses.replace(c12, video=(
        dataclasses.replace(c12.video[0], url="rtsp://{host}:554/stream=1"),
        VideoStream("thermal", "rtsp://{host}:555/stream=2", "thermal", 45.0),
    ))  # fmt: skip


def test_video_url_per_model_and_lens() -> None:
    from topgimbal.protocol import all_models, get_model

    model_names = list(all_models())

    # TOPOTEK's document gives these two; every other URL is whatever the model's profile says.
    assert video_url("SIP", "192.168.144.108", "visible") == "rtsp://192.168.144.108:554/stream=0"
    assert video_url("SIP", "192.168.144.108", "thermal") == "rtsp://192.168.144.108:554/stream=1"
    checked = 0
    for name in model_names:
        model = get_model(name)[1]
        for lens in ("visible", "thermal"):
            stream = model.video_stream(lens)
            if stream is None:
                with pytest.raises(VideoError, match=f"no '{lens}' stream"):
                    video_url(name, "192.168.144.108", lens)
            else:
                assert video_url(name, "192.168.144.108", lens) == stream.url_for("192.168.144.108")
                checked += 1
    assert checked >= len(model_names)
    assert video_url(_two_port_c12(), "10.0.0.2", "thermal") == "rtsp://10.0.0.2:555/stream=2"


@pytest.mark.loopback
def test_streams_carry_the_profiles_lens_data() -> None:
    from topgimbal.protocol import get_model
    from topgimbal.video.lens import stream_urls, vfov_for

    sip = get_model("SIP")[1]
    visible, thermal = streams_for("SIP")
    assert (visible.hfov_deg, thermal.hfov_deg) == (sip.video[0].hfov_deg, sip.video[1].hfov_deg)
    assert (visible.port, visible.path, thermal.path) == (554, "/stream=0", "/stream=1")
    # ENT numbers the streams in the profile's order: the catalog's stream0 / stream1
    assert (visible.codec_setting, thermal.codec_setting) == ("stream0", "stream1")
    assert streams_for("C12")[0].codec_setting is None  # SkyDroid has no encoding setting
    # the vertical field of view of a pinhole with the picture's aspect ratio
    w, h = visible.size
    assert math.tan(math.radians(visible.vfov_deg) / 2) == pytest.approx(math.tan(math.radians(56.0) / 2) * h / w)
    assert vfov_for(90.0, 100, 100) == pytest.approx(90.0)
    assert stream_urls(_two_port_c12(), "127.0.0.1", port=9000) == {
        "visible": "rtsp://127.0.0.1:9000/stream=1",
        "thermal": "rtsp://127.0.0.1:9001/stream=2",
    }
    with pytest.raises(VideoError, match="no model 'X9'"):
        streams_for("X9")


@pytest.mark.loopback
def test_video_url_refuses_what_the_model_has_not() -> None:
    with pytest.raises(VideoError, match="no 'thermal' stream"):
        video_url("C10", "10.0.0.1", "thermal")
    with pytest.raises(VideoError, match="lens must be one of"):
        video_url("C12", "10.0.0.1", "infrared")
    assert video_url("C12", "::1", port=8554) == "rtsp://[::1]:8554/stream=1"
    assert host_of("udp://127.0.0.1:5000") == "127.0.0.1"
    with pytest.raises(VideoError, match="host="):
        host_of("serial:///dev/ttyUSB0")


@pytest.mark.parametrize(("yaw", "pitch", "roll", "zoom"), [(0, 0, 0, 1), (37, -22, 5, 1), (-120, 40, -10, 3.5)])
def test_pixel_to_angle_inverts_angle_to_pixel(yaw: float, pitch: float, roll: float, zoom: float) -> None:
    view = View(yaw, pitch, roll, hfov_at(62.0, zoom), 1280, 720)
    for x, y in ((640, 360), (10, 700), (1200, 40)):
        az, el = view.angles_at(x, y)
        px = view.project(az, el)
        assert px is not None and px[0] == pytest.approx(x, abs=1e-6) and px[1] == pytest.approx(y, abs=1e-6)
    # The centre pixel is where the camera points; the right edge is half the field of view right.
    assert view.angles_at(640, 360) == pytest.approx(((yaw + 180) % 360 - 180, pitch), abs=1e-9)
    if roll == 0 and pitch == 0:
        assert view.angles_at(1280, 360)[0] == pytest.approx(yaw + view.hfov_deg / 2)


def test_zoom_narrows_the_field_of_view_like_a_longer_focal_length() -> None:
    assert hfov_at(62, 1) == pytest.approx(62)
    assert math.tan(math.radians(hfov_at(62, 4)) / 2) == pytest.approx(math.tan(math.radians(31)) / 4)


def test_ports_keep_the_documented_spacing() -> None:
    c12 = streams_for(_two_port_c12())
    assert plan_ports(c12, None) == {554: 554, 555: 555}
    assert plan_ports(c12, 8554) == {554: 8554, 555: 8555}
    assert plan_ports(c12, 0) == {554: 0, 555: 0}
    with pytest.raises(VideoError, match="fps"):
        VideoOptions(fps=0)
    with pytest.raises(VideoError, match="even"):
        VideoOptions(size=(641, 480))


def test_rtp_fragments_big_nal_units_and_marks_the_last_packet() -> None:
    sps, pps, idr = b"\x67\x42\xc0\x1f\x01", b"\x68\xce\x3c\x80", b"\x65" + bytes(range(256)) * 20
    au = b"\x00\x00\x00\x01" + sps + b"\x00\x00\x01" + pps + b"\x00\x00\x00\x01" + idr
    assert split_nals(au) == [sps, pps, idr]
    assert parameter_sets("h264", [sps, pps, idr]) == {"sps": sps, "pps": pps}
    pk = Packetizer("h264", ssrc=7, seq=65534)
    pkts = pk.packets(au, 90000)
    assert [p[1] & 0x80 for p in pkts] == [0] * (len(pkts) - 1) + [0x80]
    assert [int.from_bytes(p[2:4], "big") for p in pkts][:3] == [65534, 65535, 0]
    assert all(len(p) <= 1412 for p in pkts)
    # Reassemble the FU-A fragments: the IDR comes back byte for byte.
    fus = [p[12:] for p in pkts[2:]]
    assert all(f[0] & 0x1F == 28 for f in fus) and fus[0][1] & 0x80 and fus[-1][1] & 0x40
    assert bytes([(fus[0][0] & 0xE0) | (fus[0][1] & 0x1F)]) + b"".join(f[2:] for f in fus) == idr
    text = sdp("h264", {"sps": sps, "pps": pps})
    assert "profile-level-id=42C01F" in text and "sprop-parameter-sets=Z0LAHwE=,aM48gA==" in text


def _state(**kw: object) -> SceneState:
    base = dict(
        model="C12",
        yaw_deg=0.0,
        pitch_deg=0.0,
        roll_deg=0.0,
        zoom_x=1.0,
        thermal_zoom_x=1.0,
        palette="white_hot",
        osd=True,
        recording=False,
        record_s=0.0,
        tracking="stopped",
        wall_s=1_700_000_000.123,
        frame=3,
    )
    base.update(kw)
    return SceneState(**base)  # type: ignore[arg-type]


def test_the_burned_in_timestamp_reads_back() -> None:
    for lens, w, h in (("visible", 1280, 720), ("thermal", 640, 512), ("visible", 320, 240)):
        pic = np.asarray(Renderer(lens, w, h, 40.0).render(_state()))
        assert decode_stamp(pic) == 1_700_000_000_123
    assert decode_stamp(np.zeros((240, 320, 3), np.uint8)) is None


def test_thermal_picture_follows_the_palette_and_osd_and_recording_show() -> None:
    r = Renderer("thermal", 640, 512, 32.0)
    hot = (30.0, -20.0)  # sim/scene.py's warm object, centred
    white = np.asarray(r.render(_state(yaw_deg=hot[0], pitch_deg=hot[1], osd=False)))
    black = np.asarray(r.render(_state(yaw_deg=hot[0], pitch_deg=hot[1], osd=False, palette="black_hot")))
    iron = np.asarray(r.render(_state(yaw_deg=hot[0], pitch_deg=hot[1], osd=False, palette="ironbow")))
    c = (256, 320)
    assert white[c].min() > 230 and black[c].max() < 25  # hottest: white on white hot, black on black hot
    assert int(iron[c][0]) - int(iron[c][2]) > 20  # ironbow: hot is yellow-white, not grey
    v = Renderer("visible", 640, 360, 62.0)
    corner = (slice(0, 60), slice(0, 300))
    plain = np.asarray(v.render(_state(osd=False)))[corner]
    osd = np.asarray(v.render(_state(osd=True)))[corner]
    assert np.abs(osd.astype(int) - plain).max() > 100  # text where the OSD is on
    rec_box = (slice(0, 40), slice(640 - 100, 640 - 60))
    on = np.asarray(v.render(_state(osd=True, recording=True, record_s=0.2)))[rec_box]
    off = np.asarray(v.render(_state(osd=True, recording=True, record_s=0.7)))[rec_box]
    red = lambda a: int(((a[..., 0] > 200) & (a[..., 1] < 50)).sum())  # noqa: E731
    assert red(on) > 20 and red(off) == 0  # the REC light blinks


@pytest.mark.loopback
def test_client_builds_video_urls_and_imports_only_the_stream_table() -> None:
    import ast
    from pathlib import Path

    import topgimbal

    cam = topgimbal.AsyncClient("udp://127.0.0.1:5000", model="C12")
    c12 = cam.model
    assert cam.video_url() == c12.video_stream("visible").url_for("127.0.0.1")
    assert cam.video_url("thermal", host="192.168.144.108") == c12.video_stream("thermal").url_for("192.168.144.108")
    for layer in ("client", "mavlink"):  # neither imports video: the stream table is protocol.streams
        used = {
            node.module
            for path in (Path(topgimbal.__file__).parent / layer).rglob("*.py")
            for node in ast.walk(ast.parse(path.read_text()))
            if isinstance(node, ast.ImportFrom) and node.module and node.module.split(".")[0] == "video"
        }
        assert used == set(), (layer, used)
    # the bridge's --video-out takes rtp_push through outputs/rtp_out (packetizing only: PyAV is
    # imported by its thread, never at import; nothing renders or decodes)
    import subprocess
    import sys

    probe = "import sys, topgimbal.video.rtp_push; print(sorted(m for m in ('av', 'numpy', 'PIL') if m in sys.modules))"
    assert (
        subprocess.run([sys.executable, "-c", probe], capture_output=True, text=True, check=True).stdout.strip() == "[]"
    )


def test_sip_streams_follow_the_ent_codec_setting() -> None:
    from topgimbal.sim import Simulator
    from topgimbal.video.simvideo import SimVideo

    sim = Simulator("SIP")
    video = SimVideo(sim, port=0)
    visible, thermal = video.specs
    assert (video._codec(visible), video._codec(thermal)) == ("h264", "h264")
    sim.settings["ENT"] = {"stream": "stream1", "codec": "h265"}  # what `ENT 11` leaves behind
    assert (video._codec(visible), video._codec(thermal)) == ("h264", "h265")
    assert SimVideo(sim, port=0, codec="h264")._codec(thermal) == "h264"  # --video-codec wins


def test_lag_meter_measures_how_far_behind_the_camera_a_reader_is() -> None:
    from types import SimpleNamespace

    from topgimbal.video.frames import LagMeter

    clock = iter([100.0, 100.04, 100.5, 100.52])
    meter = LagMeter(clock=lambda: next(clock))
    lags = [meter.lag_s(SimpleNamespace(time=t)) for t in (0.0, 0.033, 0.066, 0.5)]
    assert lags == pytest.approx([0.0, 0.007, 0.434, 0.02])  # fell behind at the third, caught up by the fourth
    assert meter.lag_s(SimpleNamespace(time=None)) == 0.0  # no timestamps: no judgement


@pytest.mark.parametrize(("lens", "size"), [("visible", (640, 360)), ("thermal", (320, 256))])
def test_rendering_straight_into_ycbcr_gives_the_rgb_picture(lens: str, size: tuple[int, int]) -> None:
    """The simulator renders in limited-range BT.601 Y'CbCr and only subsamples the chroma; the
    decoder's view of that picture is the RGB rendering (as FFmpeg's RGB -> YUV would give it)."""
    from topgimbal.video.encode import yuv420_frame

    state = _state(yaw_deg=25.0, pitch_deg=-8.0, recording=True, palette="ironbow")
    rgb = np.asarray(Renderer(lens, *size, 45.0).render(state)).astype(int)
    ycc_img = Renderer(lens, *size, 45.0, mode="YCbCr").render(state)
    assert ycc_img.mode == "YCbCr" and ycc_img.size == size
    ycc = np.asarray(ycc_img)
    assert ycc[..., 0].min() >= 16 and ycc[..., 0].max() <= 235  # limited range, as H.264 expects
    back = yuv420_frame(ycc_img).to_ndarray(format="rgb24").astype(int)
    diff = np.abs(back - rgb)
    # Against what the RGB path gives (FFmpeg's own RGB -> yuv420p): as close on average, and
    # the worst pixels (coloured edges, where the chroma is shared by 2x2 pixels) as close too.
    import av

    ref = np.abs(av.VideoFrame.from_ndarray(rgb.astype(np.uint8), format="rgb24").reformat(format="yuv420p")
                 .to_ndarray(format="rgb24").astype(int) - rgb)  # fmt: skip
    assert diff.mean() <= ref.mean() + 0.5
    assert np.percentile(diff, 99) <= np.percentile(ref, 99) + 5
    assert decode_stamp(back.astype(np.uint8)) == decode_stamp(rgb.astype(np.uint8)) is not None
    with pytest.raises(VideoError, match="even"):
        yuv420_frame(ycc_img.crop((0, 0, size[0] - 1, size[1])))


@pytest.mark.external
def test_tracking_requests_per_model() -> None:
    from topgimbal.protocol import get_model
    from topgimbal.video.lens import tracking_requests

    c12, sip, c10 = get_model("C12"), get_model("SIP"), get_model("C10")
    # SkyDroid: GOT at the point (or the box's centre) in the 1280x720 its catalog fields span
    assert tracking_requests(*c12, 0.5, 0.25) == [("GOT", {"x_px": 640, "y_px": 180})]
    assert tracking_requests(*c12, 0.2, 0.2, 0.4, 0.6) == [("GOT", {"x_px": 384, "y_px": 288})]
    # TOPOTEK: LOC alone, centre 0 and edges +-1000 (ArduPilot's (px - 960) / 0.96 of 1920x1080)
    ((ident, box),) = tracking_requests(*sip, 0.4, 0.4, 0.6, 0.6)
    assert ident == "LOC" and box == {"x_px": 0, "y_px": 0, "width_px": 400, "height_px": 400, "reserved": "0001"}
    ((_, corner),) = tracking_requests(*sip, 1.0, 0.0)  # a point: ArduPilot's 60 px box around it
    assert (corner["x_px"], corner["y_px"], corner["width_px"], corner["height_px"]) == (1000, -1000, 62, 111)
    assert tracking_requests(*sip, 0.6, 0.6, 0.4, 0.4) == tracking_requests(*sip, 0.4, 0.4, 0.6, 0.6)  # any corners
    sip[0].encode("LOC", **box)  # the catalog takes it
    with pytest.raises(VideoError, match="does not track"):
        tracking_requests(*c10, 0.5, 0.5)
    with pytest.raises(VideoError, match="fractions"):
        tracking_requests(*sip, 1.5, 0.5)


def test_deferred_keyframe_wishes_are_logged_once_a_minute(caplog: pytest.LogCaptureFixture) -> None:
    """Keyframes wished faster than one per KEYFRAME_MIN_INTERVAL_S wait; the info line saying so
    comes at most once a minute (logthrottle.ThrottledLog on the stream's own clock)."""
    import logging

    from topgimbal.video.rtsp_stream import Stream

    now = [100.0]
    asked: list[float] = []
    stream = Stream("/main", "h264", on_keyframe_wanted=lambda: asked.append(now[0]), clock=lambda: now[0])
    with caplog.at_level(logging.INFO, logger="topgimbal.video.rtsp"):
        stream.want_keyframe()  # asked at once
        for _ in range(5):
            stream.want_keyframe()  # within the interval: deferred
        now[0] += 59.0
        stream._last_key_t = now[0]
        stream.want_keyframe()
        now[0] += 1.0
        stream._last_key_t = now[0]
        stream.want_keyframe()  # 60 s after the first line
    lines = [r.getMessage() for r in caplog.records if "keyframes wanted faster" in r.getMessage()]
    assert asked == [100.0]
    assert stream.keyframes_deferred == 7
    assert len(lines) == 2 and lines[0].endswith("(1 deferred in all)") and lines[1].endswith("(7 deferred in all)")
