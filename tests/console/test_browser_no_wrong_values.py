"""Issue 35.6 in Debian's chromium: an error message never covers a control (it sits in the page's
flow above the panels), and a page opened while the camera is LOST shows its settings as not read,
not as values the camera never gave ("White hot", 0).

Screenshots: test-artifacts/item35-error-message.png, item35-lost-thermal.png."""

from __future__ import annotations

import time
from pathlib import Path
from typing import Any

import pytest

from .conftest import BackgroundConsole, open_console, wait_for

pytestmark = [pytest.mark.external, pytest.mark.browser, pytest.mark.integration]


def test_an_error_message_covers_no_control(browser: Any, c12: BackgroundConsole, artifacts: Path) -> None:
    errors: list[str] = []
    page = open_console(browser, c12, errors)
    try:
        page.set_viewport_size({"width": 1280, "height": 720})  # a laptop: the old corner toasts hid the lens rows
        page.get_by_test_id("angle-yaw").fill("200")
        for _ in range(5):  # a stack of them, as a few wrong clicks make
            page.get_by_test_id("btn-point").click()
        toasts = page.get_by_test_id("toasts").locator(".toast.error")
        wait_for(lambda: toasts.count() >= 3, what="error messages")
        page.screenshot(path=str(artifacts / "item35-error-message.png"))
        for y in (0, 300, 10_000):  # scrolled anywhere: the messages stay in the page's flow, over nothing
            page.evaluate(f"window.scrollTo(0, {y})")
            _assert_covers_nothing(page, toasts)
        page.evaluate("window.scrollTo(0, 0)")
    finally:
        page.context.close()


COVERED = """() => {
  const box = (e) => { const b = e.getBoundingClientRect(); return [b.left, b.top, b.right, b.bottom]; };
  const over = (a, b) => a[0] < b[2] && b[0] < a[2] && a[1] < b[3] && b[1] < a[3];
  const toasts = [...document.querySelectorAll("#toasts .toast")].map(box);
  const controls = [...document.querySelectorAll("main button, main select, main input")]
    .filter((e) => e.offsetParent !== null);
  const hit = controls.filter((c) => toasts.some((t) => over(t, box(c)))).map((c) => c.dataset.testid || c.id);
  return { toasts: toasts.length, controls: controls.length, hit };
}"""


def _assert_covers_nothing(page: Any, toasts: Any) -> None:
    """One look at the whole page (the messages expire: no element-by-element round trips)."""
    seen = page.evaluate(COVERED)
    assert seen["toasts"] >= 1 and seen["controls"] > 20, seen
    assert seen["hit"] == [], seen


def test_a_page_opened_while_lost_shows_settings_as_not_read(browser: Any, artifacts: Path) -> None:
    with BackgroundConsole("C12") as bg:
        errors: list[str] = []
        bg.run(bg.sim.stop())
        wait_for(lambda: bg.server is not None and not bg.server.cam.connected, 20, what="the link lost")  # type: ignore[union-attr]
        page = open_console(browser, bg, errors, link="lost")
        try:
            time.sleep(0.5)  # whatever the page would read, it has tried
            palette = page.get_by_test_id("field-IMG-palette")
            assert palette.evaluate("(e) => e.value") == ""
            assert "not read" in palette.evaluate("(e) => e.selectedOptions[0].text")
            interval = page.get_by_test_id("field-TAS-interval_s")
            assert interval.input_value() == ""
            panel = page.get_by_test_id("panel-thermal")
            assert "White hot" not in panel.evaluate(
                "(e) => [...e.querySelectorAll('select')].map(s => s.selectedOptions[0]?.text).join(' ')"
            )
            panel.screenshot(path=str(artifacts / "item35-lost-thermal.png"))
        finally:
            page.context.close()
        assert errors == [], errors
