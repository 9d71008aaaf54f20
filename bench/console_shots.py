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
import contextlib
import sys
import threading
import time
from collections.abc import Iterator
from pathlib import Path
from typing import Any

from playwright.sync_api import sync_playwright

from topgimbal.console import ConsoleServer

OUT = Path(sys.argv[1])
SUFFIX = sys.argv[2]
OUT.mkdir(parents=True, exist_ok=True)
ARGS = ["--no-sandbox", "--disable-gpu", "--no-first-run", "--disable-background-networking"]


@contextlib.contextmanager
def console_page(browser: Any, model: str) -> Iterator[tuple[Any, Any]]:
    """(page, run) on a fresh console for a simulated `model`; `run(coro)` runs in its loop."""
    loop = asyncio.new_event_loop()
    threading.Thread(target=loop.run_forever, daemon=True).start()

    def run(coro: Any) -> Any:
        return asyncio.run_coroutine_threadsafe(coro, loop).result(30.0)

    server = ConsoleServer(sim_model=model, host="127.0.0.1", port=0)
    run(server.start())
    try:
        page = browser.new_context(viewport={"width": 1400, "height": 1100}).new_page()
        page.goto(server.page_url)
        page.wait_for_selector("body[data-ready='1']", timeout=20_000)
        run.server = server  # type: ignore[attr-defined]
        yield page, run
    finally:
        run(server.stop())
        loop.call_soon_threadsafe(loop.stop)


def shot(page: Any, testid: str, name: str) -> None:
    path = OUT / f"{name}-{SUFFIX}.png"
    page.get_by_test_id(testid).screenshot(path=str(path))
    print(path, path.stat().st_size)


def item2(browser: Any) -> None:
    with console_page(browser, "C12") as (page, _):
        page.get_by_test_id("angle-yaw").fill("200")
        page.get_by_test_id("angle-pitch").fill("0")
        page.get_by_test_id("btn-point").click()
        time.sleep(3)
        shot(page, "panel-attitude", "item2-refused-yaw")
        shot(page, "panel-pointing", "item2-pointing")


def item3(browser: Any) -> None:
    with console_page(browser, "C12") as (page, run):
        time.sleep(2)
        run(run.server.sim.stop())  # the camera goes silent (UDP: nothing says so)
        time.sleep(15)
        page.evaluate(
            "document.getElementById('panel-video') && (document.getElementById('panel-video').hidden = true)"
        )
        path = OUT / f"item3-lost-{SUFFIX}.png"
        page.screenshot(path=str(path), clip={"x": 0, "y": 0, "width": 1400, "height": 560})
        print(path, path.stat().st_size)


def item10(browser: Any) -> None:
    with console_page(browser, "C13") as (page, _):
        time.sleep(2)
        shot(page, "panel-attitude", "item10-attitude-c13")
    with console_page(browser, "C12") as (page, _):
        page.get_by_test_id("read-IMG").click()
        time.sleep(1)
        shot(page, "panel-thermal", "item10-thermal-c12")
        time.sleep(11)  # two SD polls
        shot(page, "panel-traffic", "item10-traffic")
    with console_page(browser, "SIP") as (page, _):
        time.sleep(1)
        shot(page, "panel-camera", "item10-camera-sip")


with sync_playwright() as p:
    chromium = p.chromium.launch(executable_path="/usr/bin/chromium", headless=True, args=ARGS)
    only = set(sys.argv[3:]) or {"2", "3", "10"}
    for item, take in (("2", item2), ("3", item3), ("10", item10)):
        if item in only:
            take(chromium)
    chromium.close()
