"""The console shows the camera's target position as one "lat, lon" text and copies it."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import pytest

from .conftest import BackgroundConsole, open_console, wait_for

pytestmark = pytest.mark.external

TOL = 0.5


def test_target_position_shown_and_copied(
    browser: Any, sip: BackgroundConsole, artifacts: Path, page_errors: list[str]
) -> None:
    page = open_console(browser, sip, page_errors)
    try:
        copy = page.get_by_test_id("btn-copy-target")
        assert copy.is_disabled()  # nothing to copy before the camera has said where it looks
        page.locator("#vehicle-box summary").click()
        for ident, field, value in (("ALT", "alt_m", "120"), ("LAT", "lat_deg", "46.5"), ("LON", "lon_deg", "7.25")):
            page.get_by_test_id(f"field-{ident}-{field}").fill(value)
            page.get_by_test_id(f"set-{ident}").click()
        wait_for(
            lambda: sip.call(lambda: sip.sim.device.position.lon_deg) == 7.25, what="the position in the simulator"
        )
        page.get_by_test_id("angle-yaw").fill("0")
        page.get_by_test_id("angle-pitch").fill("-45")
        page.get_by_test_id("btn-point").click()
        wait_for(lambda: abs(sip.call(lambda: sip.sim.gimbal.pitch_deg) + 45) < TOL, 20, what="the gimbal pitched down")
        page.get_by_test_id("btn-range-single").click()
        pos = page.get_by_test_id("target-pos")
        wait_for(lambda: "," in pos.inner_text(), 8, what="the target position")
        lat, lon = (float(v) for v in pos.inner_text().split(","))
        assert lat == pytest.approx(46.5 + 120 / 111195, abs=2e-4)  # 120 m up, 45 deg down: 120 m north
        assert lon == pytest.approx(7.25, abs=1e-5)
        assert not copy.is_disabled()
        copy.click()
        wait_for(lambda: copy.get_attribute("data-copied") is not None, 5, what="the copy")
        assert copy.get_attribute("data-copied") == pos.inner_text()
    finally:
        page.context.close()
    assert page_errors == [], page_errors
