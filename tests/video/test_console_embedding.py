"""No other web page can use the loopback console (issue 27): a page served from another origin
(here another port of 127.0.0.1, which browsers count as the same *site*) that embeds the
console's MJPEG streams, frames its page or fetches its JSON gets nothing, and the operator's own
page still plays. Before: such a page took 8 of 12 streams and the operator's viewer got 503."""

from __future__ import annotations

import contextlib
import http.server
import logging
import threading
from collections.abc import Iterator
from typing import Any

import pytest

from console.conftest import BackgroundConsole, open_console, wait_for, wait_for_testid

pytestmark = [pytest.mark.external, pytest.mark.browser, pytest.mark.integration]


@pytest.fixture(scope="module")
def console_c12() -> Iterator[BackgroundConsole]:
    with BackgroundConsole("C12") as bg:
        yield bg


@contextlib.contextmanager
def other_site(html: str) -> Iterator[str]:
    """A page served on another loopback port: another origin than the console's."""

    class Handler(http.server.BaseHTTPRequestHandler):
        def do_GET(self) -> None:
            body = html.encode()
            self.send_response(200)
            self.send_header("Content-Type", "text/html")
            self.send_header("Content-Length", str(len(body)))
            self.end_headers()
            self.wfile.write(body)

        def log_message(self, *args: Any) -> None:
            pass

    server = http.server.ThreadingHTTPServer(("127.0.0.1", 0), Handler)
    thread = threading.Thread(target=server.serve_forever, daemon=True)
    thread.start()
    try:
        yield f"http://127.0.0.1:{server.server_address[1]}/"
    finally:
        server.shutdown()
        server.server_close()


def _viewers(bg: BackgroundConsole) -> int:
    assert bg.server is not None and bg.server.video is not None
    return int(bg.call(lambda: sum(r.viewers for r in bg.server.video.relays.values())))  # type: ignore[union-attr]


def _webrtc_peers(bg: BackgroundConsole) -> int:
    assert bg.server is not None and bg.server.video is not None
    whep = bg.server.video.whep
    return 0 if whep is None else int(bg.call(lambda: len(whep.sessions)))


def test_a_page_from_another_origin_gets_no_console_stream(
    browser: Any, console_c12: BackgroundConsole, caplog: Any
) -> None:
    caplog.set_level(logging.WARNING, "topgimbal.console.guard")
    base = console_c12.base
    imgs = "".join(f'<img class="steal" src="{base}video/visible.mjpg?n={i}">' for i in range(12))
    html = f"""<!doctype html><html><body>{imgs}
<iframe id="frame" src="{base}"></iframe>
<script>
window.fetched = "pending";
fetch("{base}api/status").then(r => r.text()).then(t => window.fetched = t, e => window.fetched = "error");
fetch("{base}video/thermal.mjpg", {{mode: "no-cors"}}).then(() => window.noCors = "opaque", () => window.noCors = "error");
</script></body></html>"""
    with other_site(html) as url:
        context = browser.new_context()
        evil = context.new_page()
        try:
            evil.goto(url, wait_until="domcontentloaded")  # MJPEG streams never finish loading
            wait_for(lambda: evil.evaluate("window.fetched") != "pending", 15, what="the fetch settled")
            evil.wait_for_timeout(1500)  # time for the pictures to arrive (before: 8 of the 12 did)
            assert _viewers(console_c12) == 0
            # Every embedded request reached the console and was refused (what the guard logged).
            wait_for(lambda: sum("refused GET /video/visible.mjpg" in r.getMessage() for r in caplog.records) >= 1,
                     15, what="the refusal logged")  # fmt: skip
            widths = evil.evaluate("[...document.querySelectorAll('img.steal')].map(i => i.naturalWidth)")
            assert widths == [0] * 12
            assert evil.evaluate("window.fetched") == "error"  # no readable answer
            lines = [r.getMessage() for r in caplog.records if "refused" in r.getMessage()]
            assert any("Sec-Fetch-Site 'same-site'" in x for x in lines), lines  # another port: same site
            assert any(x.startswith("refused GET / ") for x in lines), lines  # the iframe
            # The operator's own page still plays, while the other page stays open.
            errors: list[str] = []
            page = open_console(browser, console_c12, errors)
            try:
                wait_for_testid(page, "video-visible", "e.naturalWidth === 1280")
                assert _viewers(console_c12) + _webrtc_peers(console_c12) >= 1  # the path the page plays
            finally:
                page.context.close()
        finally:
            context.close()
