"""The console's WebRTC in Debian's chromium: the page plays each lens over WHEP (the camera's
H.264, no re-encoding), says so, and the picture moves; its burned-in stamps give the latency.
`?video=mjpeg` keeps the MJPEG relay, and the page says that too."""

from __future__ import annotations

import statistics
from collections.abc import Iterator
from typing import Any

import pytest

from console.conftest import BackgroundConsole, open_console, wait_for_testid

pytestmark = [pytest.mark.external, pytest.mark.browser, pytest.mark.integration]


@pytest.fixture(scope="module")
def console_c12() -> Iterator[BackgroundConsole]:
    with BackgroundConsole("C12") as bg:
        yield bg


def test_each_lens_plays_over_webrtc_and_moves(browser: Any, console_c12: BackgroundConsole, artifacts: Any) -> None:
    errors: list[str] = []
    page = open_console(browser, console_c12, errors)
    try:
        page.wait_for_selector("[data-testid=panel-video]:not([hidden])", timeout=30_000)
        for lens, width in (("visible", 1280), ("thermal", 640)):
            page.wait_for_function(
                f"(() => {{ const v = document.querySelector('[data-testid=video-{lens}]');"
                f" return v && v.tagName === 'VIDEO' && v.videoWidth === {width}; }})()",
                timeout=30_000,
            )
        path = page.get_by_test_id("video-path").inner_text()
        assert "visible WebRTC" in path and "thermal WebRTC" in path, path
        # The picture moves: the video's current time advances and the burned-in stamps change.
        t0 = page.evaluate("document.querySelector('[data-testid=video-visible]').currentTime")
        page.wait_for_function("window.__videoLatency.length >= 8", timeout=30_000)
        stamps_ms = page.evaluate("window.__videoLatency.slice()")
        t1 = page.evaluate("document.querySelector('[data-testid=video-visible]').currentTime")
        assert t1 > t0
        page.screenshot(path=str(artifacts / "console-webrtc.png"))
        latency = statistics.median(stamps_ms)
        print(f"console WebRTC glass-to-glass: median {latency:.0f} ms over {len(stamps_ms)} readings")
        assert latency > 0  # a stamp read from the picture, behind the clock: a live picture
        # the server has one WebRTC peer per lens, and its MJPEG relay has no viewer
        assert console_c12.server is not None and console_c12.server.video is not None
        video = console_c12.server.video
        assert video.whep is not None
        whep = video.whep
        peers = console_c12.call(lambda: {lens: whep.peers(lens) for lens in ("visible", "thermal")})
        assert peers == {"visible": 1, "thermal": 1}
        assert console_c12.call(lambda: [r.viewers for r in video.relays.values()]) == [0, 0]
        assert not [e for e in errors if "WebRTC" in e or "RTCPeerConnection" in e], errors
    finally:
        page.context.close()


def test_video_mjpeg_in_the_url_keeps_the_relay(browser: Any, console_c12: BackgroundConsole) -> None:
    errors: list[str] = []
    context = browser.new_context(viewport={"width": 1400, "height": 1100})
    page = context.new_page()
    try:
        url = console_c12.url
        page.goto(url + ("&" if "?" in url else "?") + "video=mjpeg")
        page.wait_for_selector("[data-testid=panel-video]:not([hidden])", timeout=30_000)
        wait_for_testid(page, "video-visible", "e.tagName === 'IMG' && e.naturalWidth === 1280")
        assert "visible MJPEG" in page.get_by_test_id("video-path").inner_text()
    finally:
        context.close()
    assert not errors
