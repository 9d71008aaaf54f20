"""Fixtures for the console tests: a simulator + console running in a background event loop
(so the synchronous Playwright API can drive Debian's chromium from the test thread)."""

from __future__ import annotations

import asyncio
import os
import shutil
import threading
import time
from collections.abc import Callable, Coroutine, Iterator
from concurrent.futures import Future
from pathlib import Path
from typing import Any, TypeVar

import pytest

from topgimbal.console import ConsoleServer
from waiting import until, until_blocking

T = TypeVar("T")

ARTIFACTS = Path(__file__).resolve().parents[2] / "test-artifacts"
CHROMIUM = "/usr/bin/chromium"
LAUNCH_ARGS = [
    "--no-sandbox",
    "--disable-gpu",
    "--disable-quic",
    "--no-first-run",
    "--disable-background-networking",
    "--disable-component-update",
    "--disable-sync",
    "--allow-loopback-in-peer-connection",  # WebRTC to the console on 127.0.0.1 (tests/video/test_console_webrtc.py)
    # Host candidates as plain addresses, not mDNS names: no multicast name announcements or queries
    # leave the machine; the console keeps only the loopback ones (video/webrtc.remote_candidates).
    "--disable-features=WebRtcHideLocalIpsWithMdns",
]


class BackgroundConsole:
    """ConsoleServer(sim_model=...) on 127.0.0.1, port 0, in its own thread and event loop."""

    def __init__(self, model: str, *, token: str | None = None, seed: int = 0) -> None:
        self.model = model
        self.token = token
        self.seed = seed
        self.loop = asyncio.new_event_loop()
        self.thread = threading.Thread(target=self.loop.run_forever, name=f"console-{model}", daemon=True)
        self.server: ConsoleServer | None = None

    def __enter__(self) -> BackgroundConsole:
        self.thread.start()
        self.server = ConsoleServer(
            sim_model=self.model, sim_seed=self.seed, host="127.0.0.1", port=0, token=self.token
        )
        self.run(self.server.start())
        return self

    def __exit__(self, *exc: object) -> None:
        if self.server is not None:
            self.run(self.server.stop())
        self.loop.call_soon_threadsafe(self.loop.stop)
        self.thread.join(5)
        self.loop.close()

    def run(self, coro: Coroutine[Any, Any, T], timeout: float = 20.0) -> T:
        fut: Future[T] = asyncio.run_coroutine_threadsafe(coro, self.loop)
        return fut.result(timeout)

    def call(self, fn: Callable[[], T]) -> T:
        """Run `fn()` in the server's loop thread (to read simulator state consistently)."""

        async def wrap() -> T:
            return fn()

        return self.run(wrap())

    @property
    def sim(self) -> Any:
        assert self.server is not None
        return self.server.sim

    @property
    def url(self) -> str:
        assert self.server is not None
        return self.server.page_url

    @property
    def base(self) -> str:
        assert self.server is not None
        return self.server.base_url


def wait_for(predicate: Callable[[], Any], timeout: float = 30.0, interval: float = 0.05, what: str = "") -> Any:
    """Poll `predicate` until it returns something truthy (tests/waiting.py); return it."""
    return until_blocking(what or str(predicate), predicate, bound_s=timeout, every_s=interval)


def screenshot(locator: Any, path: Path, attempts: int = 5) -> None:
    """A picture of one element of the page, which must show something (a blank element's PNG is
    under 1000 bytes). Headless Chromium may capture an element it has just scrolled into view
    before its tiles are rasterised (seen once in five loaded runs: the panel's background without
    its text, right after that text was read from the DOM): it is then taken again, a few times,
    before the test fails."""
    sizes: list[int] = []
    for _ in range(attempts):
        locator.screenshot(path=str(path))
        sizes.append(path.stat().st_size)
        if sizes[-1] > 1000:
            return
        time.sleep(0.5)
    raise AssertionError(f"{path.name}: every screenshot was blank (PNG sizes {sizes} bytes)")


@pytest.fixture(scope="module")
def c12() -> Iterator[BackgroundConsole]:
    with BackgroundConsole("C12") as bg:
        yield bg


@pytest.fixture(scope="module")
def c10() -> Iterator[BackgroundConsole]:
    with BackgroundConsole("C10") as bg:
        yield bg


@pytest.fixture(scope="session")
def artifacts() -> Path:
    ARTIFACTS.mkdir(parents=True, exist_ok=True)
    return ARTIFACTS


@pytest.fixture(scope="module")
def browser() -> Iterator[Any]:
    """Module scope: Playwright's sync API keeps an event loop running in this thread while it is
    open, which the asyncio tests of other modules must not see."""
    if not (os.path.exists(CHROMIUM) or shutil.which("chromium")):
        pytest.fail(f"{CHROMIUM} is missing: `make test` installs Debian's chromium (apt-get install chromium)")
    from playwright.sync_api import sync_playwright

    with sync_playwright() as p:
        b = p.chromium.launch(executable_path=CHROMIUM, headless=True, args=LAUNCH_ARGS)
        yield b
        b.close()


@pytest.fixture
def page_errors() -> list[str]:
    return []


def wait_for_testid(page: Any, testid: str, condition: str = "true", timeout_s: float = 30.0) -> None:
    """Wait until the page's element `[data-testid=testid]` exists and the JavaScript `condition` on
    it (named `e`) holds. The page builds some elements after it loads (the video panel's, once its
    fetch of api/video answers): a bare `document.querySelector(...).x` in a wait throws until then,
    and Playwright ends the wait at the first throw (a fresh-clone run at load 8: "Cannot read
    properties of null (reading 'naturalWidth')" a moment after the page was ready)."""
    script = f"(() => {{ const e = document.querySelector('[data-testid={testid}]'); return e !== null && ({condition}); }})()"
    page.wait_for_function(script, timeout=timeout_s * 1000)


def open_console(browser: Any, bg: BackgroundConsole, errors: list[str], link: str = "up") -> Any:
    """A fresh page on the console, loaded, its WebSocket open and the link badge at `link`."""
    context = browser.new_context(viewport={"width": 1400, "height": 1100})
    page = context.new_page()
    page.on("pageerror", lambda exc: errors.append(str(exc)))
    page.on("console", lambda msg: errors.append(msg.text) if msg.type == "error" else None)
    page.goto(bg.url)
    page.wait_for_selector("body[data-ready='1']", timeout=30_000)
    # the video panel (above the controls) shown or not: nothing moves under a pointer after this
    page.wait_for_selector("body[data-video]", state="attached", timeout=30_000)
    wait_for_testid(page, "link", f"e.dataset.state === '{link}'")
    return page


@pytest.fixture(scope="module")
def sip() -> Iterator[BackgroundConsole]:
    with BackgroundConsole("SIP") as bg:
        yield bg


@pytest.fixture
def page(browser: Any, c12: BackgroundConsole, page_errors: list[str]) -> Iterator[Any]:
    """A fresh page on the shared C12 console; no script error may happen on it."""
    p = open_console(browser, c12, page_errors)
    yield p
    p.context.close()
    assert page_errors == [], page_errors


async def eventually(check: Callable[[], Any], timeout: float = 30.0, what: str = "condition") -> None:
    """`wait_for` for a test that runs in the event loop: poll without blocking it."""
    await until(what, check, bound_s=timeout)
