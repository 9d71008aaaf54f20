"""Issue 26, items 9 and 10, in Debian's chromium against the simulator.

Item 9: what the page shows is what the camera last said: a Set shows the value read back (and,
refused, the camera's value and the error), a row follows answers and echoes whoever asked (the
digital zoom after the video's wheel), the lens rows are read on load, and a click on the video
moves the commanded-yaw marker to the yaw the camera acknowledged.
Item 10: "- wide / + tele" step the digital zoom on a fixed-lens C12, run the motor on an optical
zoom (C10), and are disabled with the reason on a C13; tracking started by a box shows its state
and has a Stop; each picture has its own overlay side by side; a camera without video where the
model says gives one message per lens naming the URL and the `--video-url` option, and
`--video-url` / `--video-port` find a stream elsewhere."""

from __future__ import annotations

import json
import re
import subprocess
import sys
from collections.abc import Iterator
from typing import Any

import pytest

from waiting import until_blocking

from .conftest import BackgroundConsole, open_console, wait_for, wait_for_testid

# serial: drags and timed page checks in a real browser; make test runs them apart from the
# parallel pass, where a loaded CPU (six workers on two cores) delays the page, not the console.
pytestmark = [pytest.mark.external, pytest.mark.browser, pytest.mark.integration, pytest.mark.serial]


class UrlConsole(BackgroundConsole):
    """A console given a camera's URL (a simulator started apart, without video unless asked)."""

    def __init__(self, model: str, *, video: bool = False, **console: Any) -> None:
        super().__init__(model)
        self.video = video
        self.console = console
        self.camera: Any = None
        self.sim_video: Any = None

    def __enter__(self) -> UrlConsole:
        from topgimbal.sim import Simulator

        self.thread.start()
        self.camera = Simulator(model=self.model)
        self.run(self.camera.start(udp=[("127.0.0.1", 0)]))
        if self.video:
            from topgimbal.video.simvideo import SimVideo, VideoOptions

            self.sim_video = self.run(SimVideo(self.camera, VideoOptions(port=0, fps=10)).start())
        return self

    def serve(self, **console: Any) -> None:
        from topgimbal.console import ConsoleServer

        self.server = ConsoleServer(url=self.camera.url, model=self.model, host="127.0.0.1", port=0, **console)
        self.run(self.server.start())

    def unserve(self) -> None:
        if self.server is not None:
            self.run(self.server.stop())
            self.server = None

    def __exit__(self, *exc: object) -> None:
        self.unserve()
        if self.sim_video is not None:
            self.run(self.sim_video.stop())
        self.run(self.camera.stop())
        self.loop.call_soon_threadsafe(self.loop.stop)
        self.thread.join(5)
        self.loop.close()


@pytest.fixture(scope="module")
def c13() -> Iterator[BackgroundConsole]:
    with BackgroundConsole("C13") as bg:
        yield bg


def video_ready(page: Any, lens: str = "visible") -> None:
    page.wait_for_selector("[data-testid=panel-video]:not([hidden])", timeout=30_000)
    wait_for_testid(page, f"video-{lens}", "e.naturalWidth > 0")
    page.get_by_test_id(f"video-{lens}").wait_for(state="visible", timeout=30_000)


def palette_label(page: Any, name: str) -> str:
    return str(page.get_by_test_id("field-IMG-palette").locator(f"option[value={name}]").inner_text())


# -- item 9: what the camera last said ---------------------------------------------------------------


def test_set_shows_the_value_read_back_and_follows_other_clients(page: Any, c12: BackgroundConsole) -> None:
    result = page.get_by_test_id("result-IMG")
    page.get_by_test_id("field-IMG-palette").select_option("black_hot")
    page.get_by_test_id("set-IMG").click()
    wait_for(lambda: c12.call(lambda: c12.sim.thermal["IMG"]["palette"]) == "black_hot", what="the palette set")
    wait_for(lambda: result.inner_text() == "Black hot", what="the value read back after Set")
    assert result.get_attribute("data-state") == "camera"
    # another client changes it: the row shows the camera's new value by itself, select included
    c12.run(c12.server.cam.request("IMG", palette="ironbow"))  # type: ignore[union-attr]
    wait_for(lambda: result.inner_text() == "Ironbow", what="the row following the camera's echo")
    assert page.get_by_test_id("field-IMG-palette").input_value() == "ironbow"


def test_a_refused_set_shows_the_cameras_value_and_the_error(
    browser: Any, c12: BackgroundConsole, page_errors: list[str]
) -> None:
    """The camera refuses the palette (played by Playwright between page and console): the row
    shows the value the camera still has, read back, and why the Set failed."""
    context = browser.new_context(viewport={"width": 1400, "height": 1100})
    page = context.new_page()
    page.on("pageerror", lambda exc: page_errors.append(str(exc)))

    def route(ws: Any) -> None:
        server = ws.connect_to_server()

        def from_page(message: str | bytes) -> None:
            op = json.loads(message) if isinstance(message, str) else {}
            if op.get("op") == "request" and (op.get("values") or {}).get("palette") == "rainbow":
                ws.send(json.dumps({"type": "error", "ref": op["ref"], "op": "request", "kind": "device",
                                    "message": "the camera refused IMG: it answered ERE"}))  # fmt: skip
            else:
                server.send(message)

        ws.on_message(from_page)
        server.on_message(lambda message: ws.send(message))

    page.route_web_socket(re.compile(r".*/ws(\?.*)?$"), route)
    try:
        page.goto(c12.url)
        page.wait_for_selector("body[data-ready='1']", timeout=30_000)
        have = c12.call(lambda: c12.sim.thermal["IMG"]["palette"])
        page.get_by_test_id("field-IMG-palette").select_option("rainbow")
        page.get_by_test_id("set-IMG").click()
        result = page.get_by_test_id("result-IMG")
        wait_for(lambda: "not set" in result.inner_text(), what="the refusal in the row")
        text = result.inner_text()
        assert text.startswith(palette_label(page, have)) and "answered ERE" in text, text
        assert result.get_attribute("data-state") == "refused"
        assert page.get_by_test_id("field-IMG-palette").input_value() == have  # the camera's, not the refused one
    finally:
        context.close()
    assert page_errors == [], page_errors


def test_the_digital_zoom_row_shows_the_cameras_level(browser: Any, c12: BackgroundConsole) -> None:
    errors: list[str] = []
    c12.run(c12.server.cam.digital_zoom(4))  # type: ignore[union-attr]
    page = open_console(browser, c12, errors)
    try:
        select, result = page.get_by_test_id("field-DZM-zoom"), page.get_by_test_id("result-DZM")
        assert select.input_value() == "4x" and result.inner_text() == "4x"  # read on load
        video_ready(page)
        box = page.get_by_test_id("video-visible").bounding_box()
        page.mouse.move(box["x"] + box["width"] / 2, box["y"] + box["height"] / 2)
        page.mouse.wheel(0, 100)  # the video's wheel: one step out, by the console's own route
        wait_for(lambda: c12.call(lambda: c12.sim.camera.digital_zoom_x) == 3.0, 30, what="3x in the camera")
        wait_for(lambda: select.input_value() == "3x" and result.inner_text() == "3x", 10, what="the row at 3x")
    finally:
        c12.run(c12.server.cam.digital_zoom(1))  # type: ignore[union-attr]
        page.context.close()
    assert errors == [], errors


def test_folded_camera_settings_are_read_when_unfolded(page: Any) -> None:
    rows = page.get_by_test_id("camera-settings").locator(".cmdrow:has([data-testid^=read-])")
    assert rows.count() >= 3
    results = page.get_by_test_id("camera-settings").locator(".cmdrow:has([data-testid^=read-]) [data-testid^=result-]")
    assert all(t == "" for t in results.all_inner_texts())  # folded: nothing shown, nothing read
    page.locator("#camera-more > summary").click()
    wait_for(lambda: all(t != "" for t in results.all_inner_texts()), 15, what="every readable row read on unfolding")


def test_a_click_on_the_video_moves_the_commanded_yaw_marker(page: Any, c12: BackgroundConsole) -> None:
    video_ready(page)
    heading = page.get_by_test_id("heading")
    assert heading.get_attribute("data-target") == ""
    box = page.get_by_test_id("video-visible").bounding_box()
    page.mouse.click(box["x"] + box["width"] * 0.8, box["y"] + box["height"] * 0.5)
    wait_for(lambda: heading.get_attribute("data-target") != "", 10, what="the marker set by the click")
    acked = float(page.get_by_test_id("video-visible").evaluate("i => i.parentElement.dataset.last.split(' ')[1]"))
    assert float(heading.get_attribute("data-target")) == pytest.approx(acked)
    assert 5 < acked < 40  # right of the centre, within the C12's 60 deg picture
    wait_for(lambda: abs(float(page.get_by_test_id("yaw").inner_text()) - acked) < 1, 20, what="the gimbal there")
    page.get_by_test_id("btn-stop").click()
    wait_for(lambda: heading.get_attribute("data-target") == "", what="Stop clears it")


# -- item 10: zoom buttons, tracking, overlays, video elsewhere ----------------------------------------


def test_zoom_buttons_step_the_digital_zoom_on_a_fixed_lens_c12(page: Any, c12: BackgroundConsole) -> None:
    zoom_in, zoom_out = page.get_by_test_id("btn-zoom-in"), page.get_by_test_id("btn-zoom-out")
    assert zoom_in.is_enabled() and "fixed" in page.get_by_test_id("zoom-note").inner_text()
    assert c12.call(lambda: c12.sim.camera.digital_zoom_x) == 1.0
    zoom_in.click()
    wait_for(lambda: c12.call(lambda: c12.sim.camera.digital_zoom_x) == 2.0, 10, what="one step in: 2x")
    wait_for(lambda: page.get_by_test_id("result-DZM").inner_text() == "2x", 10, what="the level read back")
    zoom_out.click()
    wait_for(lambda: c12.call(lambda: c12.sim.camera.digital_zoom_x) == 1.0, 10, what="one step out: 1x")
    wait_for(lambda: page.get_by_test_id("field-DZM-zoom").input_value() == "1x", 10, what="the select at 1x")


def test_zoom_buttons_run_the_motor_on_an_optical_zoom(browser: Any, c10: BackgroundConsole) -> None:
    errors: list[str] = []
    page = open_console(browser, c10, errors)
    try:
        button = page.get_by_test_id("btn-zoom-in")
        assert button.is_enabled() and "optical zoom" in page.get_by_test_id("zoom-note").inner_text()
        button.hover()
        page.mouse.down()
        wait_for(lambda: c10.call(lambda: c10.sim.camera.zoom_x) > 1.2, 10, what="the optical zoom moving in")
        page.mouse.up()
        wait_for(lambda: c10.call(lambda: c10.sim.camera.zoom_dir) == 0, 10, what="stopped on release")
    finally:
        page.context.close()
    assert errors == [], errors


def test_zoom_buttons_are_disabled_with_the_reason_on_a_c13(browser: Any, c13: BackgroundConsole) -> None:
    errors: list[str] = []
    page = open_console(browser, c13, errors)
    try:
        for testid in ("btn-zoom-in", "btn-zoom-out"):
            button = page.get_by_test_id(testid)
            assert button.is_disabled()
            assert "C13's lens is fixed" in (button.get_attribute("title") or "")
        assert "change nothing" in page.get_by_test_id("zoom-note").inner_text()
    finally:
        page.context.close()
    assert errors == [], errors


def test_tracking_started_by_a_box_shows_its_state_and_stops(page: Any, c12: BackgroundConsole) -> None:
    video_ready(page)
    state, stop = page.get_by_test_id("video-tracking"), page.get_by_test_id("btn-track-stop")
    assert stop.is_hidden()
    box = page.get_by_test_id("video-visible").bounding_box()
    x0, y0 = box["x"] + box["width"] * 0.45, box["y"] + box["height"] * 0.45
    page.mouse.move(x0, y0)
    page.mouse.down()
    page.mouse.move(x0 + 50, y0 + 40, steps=4)
    page.mouse.up()
    wait_for(lambda: c12.call(lambda: c12.sim.camera.tracking) == "tracking", 10, what="tracking in the camera")
    wait_for(lambda: "tracking: on" in state.inner_text(), 10, what="the tracking state")
    assert stop.is_visible() and state.get_attribute("data-state") == "tracking"
    stop.click()
    wait_for(lambda: c12.call(lambda: c12.sim.camera.tracking) == "stopped", 10, what="tracking stopped")
    wait_for(lambda: "stopped" in state.inner_text(), 10, what="the stopped state")
    assert stop.is_hidden()


def test_tracking_on_a_sip_shows_the_cameras_state_and_stops(browser: Any, sip: BackgroundConsole) -> None:
    """TOPOTEK: the box goes as LOC, the state is the camera's answer to the tracking query, and
    Stop is the tracking command's stop."""
    errors: list[str] = []
    page = open_console(browser, sip, errors)
    try:
        video_ready(page)
        state = page.get_by_test_id("video-tracking")
        box = page.get_by_test_id("video-visible").bounding_box()
        x0, y0 = box["x"] + box["width"] * 0.4, box["y"] + box["height"] * 0.4
        page.mouse.move(x0, y0)
        page.mouse.down()
        page.mouse.move(x0 + 60, y0 + 40, steps=4)
        page.mouse.up()
        wait_for(lambda: sip.call(lambda: sip.sim.camera.tracking) != "stopped", 10, what="tracking in the camera")
        wait_for(lambda: "(the camera's state)" in state.inner_text(), 10, what="the state the camera answered")
        have = sip.call(lambda: sip.sim.camera.tracking)
        assert have in state.inner_text().lower() and state.get_attribute("data-state") == "tracking"
        page.get_by_test_id("btn-track-stop").click()
        wait_for(lambda: sip.call(lambda: sip.sim.camera.tracking) == "stopped", 10, what="tracking stopped")
        wait_for(lambda: state.get_attribute("data-state") == "stopped", 10, what="the stopped state")
        assert "stopped" in state.inner_text() and page.get_by_test_id("btn-track-stop").is_hidden()
    finally:
        page.context.close()
    assert errors == [], errors


def _inside(inner: dict[str, float], outer: dict[str, float]) -> bool:
    return (
        inner["x"] >= outer["x"] - 1
        and inner["y"] >= outer["y"] - 1
        and inner["x"] + inner["width"] <= outer["x"] + outer["width"] + 1
        and inner["y"] + inner["height"] <= outer["y"] + outer["height"] + 1
    )


BOXES_JS = """(lens) => {
  const rect = (id) => {
    const e = document.querySelector(`[data-testid=${id}]`);
    const b = e && e.getBoundingClientRect();
    return b && b.width > 0 && b.height > 0 ? { x: b.x, y: b.y, width: b.width, height: b.height } : null;
  };
  const state = document.querySelector(`[data-testid=video-state-${lens}]`);
  return { picture: rect(`video-${lens}`), overlay: rect(`video-overlay-${lens}`), state: state && state.textContent };
}"""


def test_side_by_side_each_picture_has_its_own_overlay(page: Any) -> None:
    video_ready(page, "thermal")
    wait_for(lambda: "zoom" in page.get_by_test_id("video-overlay-visible").inner_text(), 10, what="the overlay")
    assert page.get_by_test_id("video-overlay-thermal").is_hidden()  # the inset carries none
    page.get_by_test_id("video-layout").click()
    for lens in ("visible", "thermal"):
        overlay = page.get_by_test_id(f"video-overlay-{lens}")
        wait_for(lambda o=overlay: o.is_visible(), 30, what=f"the {lens} overlay")
        assert "yaw" in overlay.inner_text() and "zoom" in overlay.inner_text()
        # both boxes read at one instant (the picture and its overlay shown together); a bound on a
        # hang, and the lens's state line in the failure (its stream may be reconnecting)
        seen = until_blocking(f"the {lens} picture and overlay, both shown", lambda lens=lens: page.evaluate(BOXES_JS, lens),
                              lambda got: bool(got["picture"] and got["overlay"]), bound_s=30)  # fmt: skip
        assert _inside(seen["overlay"], seen["picture"]), f"the {lens} overlay leaves its picture: {seen}"
    page.get_by_test_id("video-layout").click()


def test_a_camera_without_video_there_gives_one_message_per_lens_and_the_option(browser: Any) -> None:
    errors: list[str] = []
    with UrlConsole("C12", video=True) as bg:
        bg.serve()  # the simulator's video is on a free port, not the documented 554
        page = open_console(browser, bg, errors)
        try:
            page.wait_for_selector("[data-testid=panel-video]:not([hidden])", timeout=30_000)
            states = {lens: page.get_by_test_id(f"video-state-{lens}") for lens in ("visible", "thermal")}
            for lens, state in states.items():
                wait_for(lambda s=state: "no video from" in s.inner_text(), 20, what=f"the {lens} message")
                text = state.inner_text()
                assert f"rtsp://127.0.0.1:554/stream={1 if lens == 'visible' else 2}" in text
                assert f"--video-url {lens}=" in text and "--video-port" in text
                assert text.count("rtsp://127.0.0.1:554") == 1  # the URL once, not repeated by the error
            a, b = (states[lens].bounding_box() for lens in ("visible", "thermal"))
            assert a["y"] + a["height"] <= b["y"] or b["y"] + b["height"] <= a["y"], "the messages overlap"
        finally:
            page.context.close()
        bg.unserve()
        port = int(bg.sim_video.urls["visible"].rsplit(":", 1)[1].split("/")[0])
        for option in ({"video_port": port}, {"video_urls": dict(bg.sim_video.urls)}):
            bg.serve(**option)
            page = open_console(browser, bg, errors)
            try:
                video_ready(page, "visible")
                video_ready(page, "thermal")
                for lens in ("visible", "thermal"):
                    state = page.get_by_test_id(f"video-state-{lens}")
                    wait_for(state.is_hidden, 20, what=f"the {lens} picture without a message ({option})")
            finally:
                page.context.close()
            bg.unserve()
    assert errors == [], errors


def test_video_url_option_parses_lenses_and_refuses_bad_values() -> None:
    from topgimbal.cli.console_cmd import video_urls

    assert video_urls("C12", ["rtsp://a/1", "rtsp://b/2?x=1"]) == {"visible": "rtsp://a/1", "thermal": "rtsp://b/2?x=1"}
    assert video_urls("C12", ["thermal=rtsp://t/1", "rtsp://v/1"]) == {"thermal": "rtsp://t/1", "visible": "rtsp://v/1"}
    cases = [
        (["--video-url", "bogus=rtsp://h/x"], "has no lens 'bogus'; its lenses: visible, thermal"),
        (["--video-url", "visible=ftp://h/x"], "expected a stream URL such as rtsp://"),
        (["--video-url", "rtsp://a/1", "--video-url", "rtsp://b/2", "--video-url", "rtsp://c/3"], "all given"),
        (["--video-port", "70000"], "give a port from 1 to 65535"),
    ]
    for extra, message in cases:
        proc = subprocess.run(
            [sys.executable, "-m", "topgimbal.cli.main", "console", "--url", "udp://127.0.0.1:9", "--model", "C12", *extra],
            capture_output=True, text=True, timeout=60,
        )  # fmt: skip
        assert proc.returncode == 2 and message in proc.stderr, (extra, proc.returncode, proc.stderr)
    proc = subprocess.run(
        [sys.executable, "-m", "topgimbal.cli.main", "console", "--sim", "C12", "--video-port", "8554"],
        capture_output=True, text=True, timeout=60,
    )  # fmt: skip
    assert proc.returncode == 2 and "are for a camera given with --url" in proc.stderr
