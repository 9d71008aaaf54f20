"""Issue 37 in Debian's chromium: the console's video panel says when the camera lost the target
(a TOPOTEK camera that was tracking reads "waiting" again without a stop) and drops the box."""

from __future__ import annotations

from typing import Any

import pytest

from topgimbal.sim.targets import parse_spec
from topgimbal.sim.tracker import unproject

from .conftest import BackgroundConsole, open_console, wait_for, wait_for_testid

pytestmark = pytest.mark.external


def test_a_lost_target_shows_as_lost_on_a_sip(browser: Any, sip: BackgroundConsole) -> None:
    errors: list[str] = []
    page = open_console(browser, sip, errors)
    try:
        page.wait_for_selector("[data-testid=panel-video]:not([hidden])", timeout=30_000)
        wait_for_testid(page, "video-visible", "e.naturalWidth > 0")
        page.get_by_test_id("video-visible").wait_for(state="visible", timeout=30_000)
        state = page.get_by_test_id("video-tracking")
        img = page.get_by_test_id("video-visible").bounding_box()
        assert img is not None
        fx, fy = 0.42, 0.42  # the middle of the box dragged below

        def place() -> None:
            st = sip.sim.device.state
            yaw, pitch, _ = st.gimbal.earth()
            az, el = unproject(yaw, pitch, fx, fy, st.tracking_hfov_deg())
            t = sip.sim.device.now - st.camera.booted_at
            # there now, hidden from 4 s on for longer than the SIP's tracker coasts
            st.targets = (parse_spec(f"bearing={az:.4f},elevation={el:.4f},size=3,hide={t + 4:.3f}-{t + 600:.3f}"),)

        sip.call(place)
        x0, y0 = img["x"] + img["width"] * (fx - 0.04), img["y"] + img["height"] * (fy - 0.05)
        page.mouse.move(x0, y0)
        page.mouse.down()
        page.mouse.move(x0 + img["width"] * 0.08, y0 + img["height"] * 0.1, steps=4)
        page.mouse.up()
        wait_for(
            lambda: sip.call(lambda: sip.sim.device.state.tracker.target) is not None, 10, what="locked on the target"
        )
        wait_for(lambda: state.get_attribute("data-state") == "tracking", 10, what="the tracking state")
        wait_for(lambda: sip.call(lambda: sip.sim.camera.tracking) == "lost", 15, what="the camera lost it")
        wait_for(lambda: state.get_attribute("data-state") == "lost", 5, what="the console says lost")
        assert "lost" in state.inner_text() and page.get_by_test_id("btn-track-stop").is_visible()
        page.get_by_test_id("btn-track-stop").click()
        wait_for(lambda: state.get_attribute("data-state") == "stopped", 10, what="the stopped state")
    finally:
        page.context.close()
        sip.call(lambda: setattr(sip.sim.device.state, "targets", ()))
    assert errors == [], errors
