"""Before/after screenshots of issue 17 items 2, 3 and 10 (docs/console.md): drives whichever
topgimbal is importable with Playwright and Debian's chromium, and prints each file's size.

    python bench/console_shots.py OUTDIR after [2 3 10]
    # "before": the same script with the tree of commit a995c83 in its own venv:
    git archive a995c83 | tar -x -C /tmp/before && (cd /tmp/before && python3 -m venv .venv &&
      .venv/bin/pip install -e '.[dev]') && /tmp/before/.venv/bin/python bench/console_shots.py OUTDIR before

docs/images/ holds them scaled to 3/4 when wider than 1000 px and reduced to 128 colours.
"""

from __future__ import annotations

import asyncio
import sys
import threading
import time
from pathlib import Path

from playwright.sync_api import sync_playwright

from topgimbal.console import ConsoleServer

OUT = Path(sys.argv[1])
SUFFIX = sys.argv[2]
OUT.mkdir(parents=True, exist_ok=True)
ARGS = ["--no-sandbox", "--disable-gpu", "--no-first-run", "--disable-background-networking"]


class Bg:
    def __init__(self, model: str) -> None:
        self.loop = asyncio.new_event_loop()
        threading.Thread(target=self.loop.run_forever, daemon=True).start()
        self.server = ConsoleServer(sim_model=model, host="127.0.0.1", port=0)
        self.run(self.server.start())

    def run(self, coro, timeout=30.0):
        return asyncio.run_coroutine_threadsafe(coro, self.loop).result(timeout)

    def close(self) -> None:
        self.run(self.server.stop())
        self.loop.call_soon_threadsafe(self.loop.stop)


def wait(pred, timeout=20.0):
    end = time.monotonic() + timeout
    while time.monotonic() < end:
        if pred():
            return True
        time.sleep(0.1)
    return False


def shot(page, testid: str, name: str) -> None:
    path = OUT / f"{name}-{SUFFIX}.png"
    page.get_by_test_id(testid).screenshot(path=str(path))
    print(path, path.stat().st_size)


def open_page(browser, bg: Bg, width: int = 1400):
    ctx = browser.new_context(viewport={"width": width, "height": 1100})
    page = ctx.new_page()
    page.goto(bg.server.page_url)
    page.wait_for_selector("body[data-ready='1']", timeout=20_000)
    return page


with sync_playwright() as p:
    browser = p.chromium.launch(executable_path="/usr/bin/chromium", headless=True, args=ARGS)
    only = set(sys.argv[3:])

    if not only or "2" in only:
        bg = Bg("C12")
        try:
            page = open_page(browser, bg)
            page.get_by_test_id("angle-yaw").fill("200")
            page.get_by_test_id("angle-pitch").fill("0")
            page.get_by_test_id("btn-point").click()
            time.sleep(3)
            shot(page, "panel-attitude", "item2-refused-yaw")
            shot(page, "panel-pointing", "item2-pointing")
        finally:
            bg.close()

    if not only or "3" in only:
        bg = Bg("C12")
        try:
            page = open_page(browser, bg)
            wait(lambda: page.get_by_test_id("link").inner_text() == "up")
            bg.run(bg.server.sim.stop())  # the camera goes silent (UDP: nothing says so)
            time.sleep(15)
            page.evaluate(
                "document.getElementById('panel-video') && (document.getElementById('panel-video').hidden = true)"
            )
            page.set_viewport_size({"width": 1400, "height": 1100})
            page.screenshot(
                path=str(OUT / f"item3-lost-{SUFFIX}.png"), clip={"x": 0, "y": 0, "width": 1400, "height": 560}
            )
            print(OUT / f"item3-lost-{SUFFIX}.png")
        finally:
            bg.close()

    if not only or "10" in only:
        bg = Bg("C13")
        try:
            page = open_page(browser, bg)
            time.sleep(2)
            shot(page, "panel-attitude", "item10-attitude-c13")
        finally:
            bg.close()
        bg = Bg("C12")
        try:
            page = open_page(browser, bg)
            page.get_by_test_id("read-IMG").click()
            time.sleep(1)
            shot(page, "panel-thermal", "item10-thermal-c12")
            time.sleep(11)  # two SD polls
            shot(page, "panel-traffic", "item10-traffic")
        finally:
            bg.close()
        bg = Bg("SIP")
        try:
            page = open_page(browser, bg)
            time.sleep(1)
            shot(page, "panel-camera", "item10-camera-sip")
        finally:
            bg.close()
    browser.close()
