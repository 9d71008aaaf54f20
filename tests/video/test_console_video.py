"""The console's video in Debian's chromium: the picture plays, a click on a landmark points the
simulated gimbal at it, and a dropped stream shows its state and comes back."""

from __future__ import annotations

import io
from collections.abc import Iterator
from typing import Any

import numpy as np
import pytest
from PIL import Image

from console.conftest import BackgroundConsole, open_console, wait_for, wait_for_testid
from topgimbal.video import world
from topgimbal.video.lens import View, stream_for
from topgimbal.video.simvideo import SimVideo, VideoOptions

from .blobs import nearest, red_blobs

pytestmark = [pytest.mark.external, pytest.mark.browser, pytest.mark.integration]


@pytest.fixture(scope="module")
def console_c12() -> Iterator[BackgroundConsole]:
    with BackgroundConsole("C12") as bg:
        yield bg


def _picture(page: Any, lens: str = "visible") -> tuple[np.ndarray, dict[str, float]]:
    img = page.get_by_test_id(f"video-{lens}")
    img.wait_for(state="visible", timeout=30_000)  # hidden while the relay reopens a stream (loaded machine)
    box = img.bounding_box()
    assert box is not None
    return np.asarray(Image.open(io.BytesIO(img.screenshot())).convert("RGB")), box


def test_video_plays_and_a_click_on_a_landmark_points_there(
    browser: Any,
    console_c12: BackgroundConsole,
    artifacts: Any,
) -> None:
    errors: list[str] = []
    page = open_console(browser, console_c12, errors)
    try:
        _play_and_point(page, console_c12, artifacts, errors)
    finally:
        page.context.close()  # the console's stop waits for its open WebSocket and picture streams


def _play_and_point(page: Any, console_c12: BackgroundConsole, artifacts: Any, errors: list[str]) -> None:
    page.wait_for_selector("[data-testid=panel-video]:not([hidden])", timeout=30_000)
    wait_for_testid(page, "video-visible", "e.naturalWidth === 1280")
    wait_for_testid(page, "video-thermal", "e.naturalWidth === 640")
    # The picture moves: two screenshots a moment apart differ (the burned-in clock runs).
    a, _ = _picture(page)
    page.wait_for_timeout(300)
    b, _ = _picture(page)
    assert np.abs(a.astype(int) - b).max() > 50
    page.screenshot(path=str(artifacts / "console-video.png"))

    # Landmark 18 (bearing -20, elevation -8) with the gimbal at 0, 0: find its bullseye in the
    # picture the browser shows, click its centre, and the gimbal turns to it.
    spec = stream_for("C12", "visible")
    m = world.landmark(18)
    px = View(0.0, 0.0, 0.0, spec.hfov_deg, *spec.size).project(m.az_deg, m.el_deg)
    assert px is not None
    pic, box = _picture(page)
    sx, sy = pic.shape[1] / spec.size[0], pic.shape[0] / spec.size[1]
    bx, by, err = nearest(red_blobs(pic, min_pixels=8), px[0] * sx, px[1] * sy)
    assert err < 6 * sx, "landmark 18 is not where the lens model puts it"
    page.mouse.click(box["x"] + bx * box["width"] / pic.shape[1], box["y"] + by * box["height"] / pic.shape[0])

    def aimed() -> bool:
        yaw, pitch, _ = console_c12.call(lambda: (console_c12.sim.device.sync(), console_c12.sim.gimbal.earth())[1])
        return abs(yaw - m.az_deg) < 1.0 and abs(pitch - m.el_deg) < 1.0

    wait_for(aimed, 20, what="the gimbal pointing at landmark 18 within 1 deg")
    # The overlay follows the attitude.
    wait_for(lambda: "yaw -2" in page.get_by_test_id("video-overlay-visible").inner_text(), 5, what="the overlay's yaw")

    # Drag a box: the C12 is told to track what it holds (GOT); the wheel zooms (digital on a C12).
    x0, y0 = box["x"] + box["width"] * 0.45, box["y"] + box["height"] * 0.45
    page.mouse.move(x0, y0)
    page.mouse.down()
    page.mouse.move(x0 + 40, y0 + 30, steps=4)
    page.mouse.up()
    wait_for(lambda: console_c12.call(lambda: console_c12.sim.camera.tracking) == "tracking", 10, what="tracking")
    page.mouse.move(box["x"] + box["width"] / 2, box["y"] + box["height"] / 2)
    page.mouse.wheel(0, -100)
    wait_for(lambda: console_c12.call(lambda: console_c12.sim.camera.digital_zoom_x) == 2.0, 10, what="2x zoom")
    wait_for(
        lambda: "zoom 2.0" in page.get_by_test_id("video-overlay-visible").inner_text(), 5, what="the overlay's zoom"
    )
    assert not [e for e in errors if "video" in e.lower()], errors


def test_a_dropped_stream_shows_its_state_and_reconnects(browser: Any) -> None:
    with BackgroundConsole("C10") as bg:
        errors: list[str] = []
        page = open_console(browser, bg, errors)
        try:
            _drop_and_reconnect(page, bg)
        finally:
            page.context.close()  # the console's stop waits for the page's WebSocket and picture streams


def _drop_and_reconnect(page: Any, bg: BackgroundConsole) -> None:
    wait_for_testid(page, "video-visible", "e.naturalWidth > 0")
    video = bg.server.video  # type: ignore[union-attr]
    port = int(video.sim_video.urls["visible"].rsplit(":", 1)[1].split("/")[0])
    bg.run(video.sim_video.stop())
    state = page.get_by_test_id("video-state-visible")
    wait_for(lambda: "reconnecting" in state.inner_text(), 15, what="the 'stream lost' state")
    video.sim_video = bg.run(SimVideo(bg.sim, VideoOptions(port=port)).start())
    wait_for(lambda: state.is_hidden(), 20, what="the picture back")

    # pictures through whichever path the page plays (WebRTC, or the MJPEG relay)
    def pictures() -> int:
        webrtc = video.whep.sources["visible"].pictures if video.whep is not None else 0
        return int(video.relays["visible"].pictures + webrtc)

    before = bg.call(pictures)
    wait_for(lambda: bg.call(pictures) > before + 5, 10, what="new pictures")


def test_video_routes_refuse_bad_requests_with_the_reason() -> None:
    import json
    import urllib.error
    import urllib.request

    def post(bg: BackgroundConsole, path: str, body: object) -> tuple[int, dict[str, Any]]:
        req = urllib.request.Request(bg.base + path.lstrip("/"), data=json.dumps(body).encode(), method="POST")
        req.add_header("Content-Type", "application/json")
        try:
            with urllib.request.urlopen(req, timeout=10) as r:
                return r.status, json.loads(r.read())
        except urllib.error.HTTPError as e:
            return e.code, json.loads(e.read())

    with BackgroundConsole("C10") as bg:
        code, body = post(bg, "/api/video/point", {"lens": "visible", "x": 1.5, "y": 0.5})
        assert code == 400 and "x must be a number from 0 to 1" in body["message"]
        code, body = post(bg, "/api/video/point", {"lens": "thermal", "x": 0.5, "y": 0.5})
        assert code == 400 and "lens must be one of visible" in body["message"]
        code, body = post(bg, "/api/video/track", {"x0": 0.1, "y0": 0.1, "x1": 0.3, "y1": 0.3})
        assert code == 409 and "does not track" in body["message"]
        code, body = post(bg, "/api/video/zoom", {"direction": "sideways"})
        assert code == 400
        assert bg.call(lambda: bg.sim.gimbal.yaw_axis.target) == 0.0  # nothing was sent
        code, body = post(bg, "/api/video/point", {"lens": "visible", "x": 1.0, "y": 0.5})
        hfov = bg.call(lambda: bg.sim.device.model.video_stream("visible").hfov_deg)  # the C10 profile's
        assert code == 200 and body["yaw_deg"] == pytest.approx(hfov / 2, abs=0.01)  # the right edge: half of it
