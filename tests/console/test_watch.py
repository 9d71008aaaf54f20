"""Issue 12, console side: `topgimbal console --proxy` runs `topgimbal.wire.proxy.Proxy` in process
and the page watches what crosses it, read-only. The simulator sits behind the proxy and a client
in front, as a ground station would."""

from __future__ import annotations

import asyncio
import subprocess
import sys
import time
from collections.abc import AsyncIterator, Iterator
from pathlib import Path
from typing import Any

import aiohttp
import pytest

from topgimbal import client
from topgimbal.console import ConsoleServer
from topgimbal.protocol import Frame
from topgimbal.sim import Simulator
from topgimbal.wire import WireFrame, frames_in_capture

from .conftest import BackgroundConsole, open_console, wait_for

pytestmark = [pytest.mark.loopback, pytest.mark.integration]

PROXY = [sys.executable, "-m", "topgimbal.cli.main", "console", "--proxy"]


@pytest.fixture
async def camera() -> AsyncIterator[Simulator]:
    sim = Simulator(model="C12")
    await sim.start(udp=[("127.0.0.1", 0)])
    try:
        yield sim
    finally:
        await sim.stop()


async def _pushes(ws: aiohttp.ClientWebSocketResponse, seconds: float) -> list[dict[str, Any]]:
    out: list[dict[str, Any]] = []
    end = time.monotonic() + seconds
    while (left := end - time.monotonic()) > 0:
        try:
            out.append(await ws.receive_json(timeout=left))
        except asyncio.TimeoutError:
            break
    return out


async def test_the_console_watches_a_proxy_read_only(camera: Simulator, tmp_path: Path) -> None:
    async with (
        ConsoleServer(proxy_listen="udp://127.0.0.1:0", proxy_to=camera.url, model="C12", port=0) as srv,
        aiohttp.ClientSession() as http,
    ):
        assert srv.proxy is not None and srv.cam is None and srv.video is None
        ws = await http.ws_connect(srv.base_url + "ws")
        hello = await ws.receive_json(timeout=30)
        assert hello["type"] == "hello" and hello["mode"] == "watch"
        assert "sends nothing to the camera" in hello["readonly"]
        assert hello["status"]["link"] == "watching"

        async with client.connect(srv.proxy.url, model="C12") as gs:  # the "ground station"
            await gs.version()
            await gs.photo()
            await gs.set_angles(yaw_deg=20, pitch_deg=-10)
            await gs.point(20, -10, timeout_s=20)
            await gs.attitude_stream(20)
            pushes = await _pushes(ws, 1.5)
            await gs.stop_attitude_stream()
            local_port = next(
                int(i["client"].rsplit(":", 1)[1])
                for p in pushes
                if p["type"] == "traffic"
                for i in p["items"]
                if i.get("client")
            )

        items = [i for p in pushes if p["type"] == "traffic" for i in p["items"]]
        items += [i for i in hello["traffic"]]
        seen = {(i["dir"], i["id"]) for i in items}
        assert {("out", "CAP"), ("in", "CAP"), ("out", "GAM"), ("in", "GAC")} <= seen
        assert all(i["client"] == f"udp 127.0.0.1:{local_port}" for i in items if i.get("id") == "CAP")
        assert any(i.get("stream") for i in items if i["id"] == "GAC")  # hidden by default like the console's own
        # the attitude read from the passing reports, in the API's signs (C12: pitch flips on the wire)
        att = [p for p in pushes if p["type"] == "attitude"]
        assert att and att[-1]["yaw"] == pytest.approx(20, abs=1.0) and att[-1]["pitch"] == pytest.approx(-10, abs=1.0)
        status = [p for p in pushes if p["type"] == "status"][-1]
        assert status["stats"]["frames_out"] >= 3 and status["stats"]["frames_in"] >= 3
        assert status["proxy"]["clients"][0]["client"] == f"udp 127.0.0.1:{local_port}"

        # read-only: an op is refused and nothing reaches the camera
        caps = sum(1 for f in camera.received if f.ident == "CAP")
        await ws.send_json({"op": "photo", "ref": 7})
        while (reply := await ws.receive_json(timeout=30)).get("ref") != 7:
            pass
        assert reply["type"] == "error" and reply["kind"] == "readonly"
        assert "sends nothing to the camera" in reply["message"]
        await asyncio.sleep(0.3)
        assert sum(1 for f in camera.received if f.ident == "CAP") == caps

        # the pcap: what crossed, each frame between its client and the camera
        async with http.get(srv.base_url + "api/traffic.pcap") as r:
            assert r.status == 200
            path = tmp_path / "watch.pcap"
            path.write_bytes(await r.read())
    cam_port = int(camera.url.rsplit(":", 1)[1])
    frames = [f for f in frames_in_capture(path) if isinstance(f, WireFrame) and isinstance(f.item, Frame)]
    cap = [f for f in frames if isinstance(f.item, Frame) and f.item.ident == "CAP"]
    assert [(f.src, f.dst) for f in cap] == [
        (("127.0.0.1", local_port), ("127.0.0.1", cam_port)),
        (("127.0.0.1", cam_port), ("127.0.0.1", local_port)),
    ]


def test_the_console_cli_watches_a_proxy() -> None:
    """`topgimbal console --proxy` starts, says it is read-only, serves the page and exits."""
    with BackgroundSim() as port:
        cmd = [*PROXY, "--listen", "udp://127.0.0.1:0", "--to", f"udp://127.0.0.1:{port}", "--model", "C12"]
        cmd += ["--port", "0", "--seconds", "2"]
        proc = subprocess.run(cmd, capture_output=True, text=True, timeout=40, check=False)
    assert proc.returncode == 0, proc.stderr
    assert "(watching the proxy: read-only)" in proc.stdout and "open http://127.0.0.1:" in proc.stdout
    bad = subprocess.run(
        [*PROXY, "--listen", "udp://127.0.0.1:0"],
        capture_output=True,
        text=True,
        timeout=40,
        check=False,
    )
    assert bad.returncode == 1 and "--proxy needs both --listen URL" in bad.stderr
    bad = subprocess.run(
        [*PROXY, "--listen", "udp://127.0.0.1:0", "--to", "udp://127.0.0.1:9", "--port", "0"],
        capture_output=True,
        text=True,
        timeout=40,
        check=False,
    )
    assert bad.returncode == 1 and "give --model with --proxy" in bad.stderr


class BackgroundSim:
    """A simulator on a loopback UDP port in its own thread (for the CLI test)."""

    def __enter__(self) -> int:
        import threading

        self.loop = asyncio.new_event_loop()
        self.thread = threading.Thread(target=self.loop.run_forever, daemon=True)
        self.thread.start()
        self.sim = Simulator(model="C12")
        asyncio.run_coroutine_threadsafe(self.sim.start(udp=[("127.0.0.1", 0)]), self.loop).result(10)
        return int(self.sim.addresses["udp"][0][1])

    def __exit__(self, *exc: object) -> None:
        asyncio.run_coroutine_threadsafe(self.sim.stop(), self.loop).result(10)
        self.loop.call_soon_threadsafe(self.loop.stop)
        self.thread.join(5)


class WatchConsole(BackgroundConsole):
    """A console watching a proxy in front of a simulator, in a background loop."""

    def __enter__(self) -> WatchConsole:
        self.thread.start()
        self.camera = Simulator(model=self.model)
        self.run(self.camera.start(udp=[("127.0.0.1", 0)]))
        self.server = ConsoleServer(
            proxy_listen="udp://127.0.0.1:0", proxy_to=self.camera.url, model=self.model, host="127.0.0.1", port=0
        )
        self.run(self.server.start())
        return self

    def __exit__(self, *exc: object) -> None:
        self.run(self.camera.stop())
        super().__exit__(*exc)


@pytest.fixture
def watched() -> Iterator[WatchConsole]:
    with WatchConsole("C12") as bg:
        yield bg


@pytest.mark.external
@pytest.mark.browser
def test_the_page_watching_a_proxy(
    browser: Any, watched: WatchConsole, artifacts: Path, page_errors: list[str]
) -> None:
    page = open_console(browser, watched, page_errors, link="watching")
    try:
        banner = page.get_by_test_id("link-banner")
        assert banner.is_visible() and "Read-only" in banner.inner_text()
        assert page.get_by_test_id("link").inner_text() == "watching"
        photo = page.get_by_test_id("btn-photo")
        assert photo.is_disabled() and "sends nothing to the camera" in (photo.get_attribute("title") or "")
        assert page.get_by_test_id("traffic-filter").is_enabled()

        async def ground_station() -> None:
            assert watched.server is not None and watched.server.proxy is not None
            async with client.connect(watched.server.proxy.url, model="C12") as gs:
                await gs.version()
                await gs.set_angles(yaw_deg=30, pitch_deg=0)
                await gs.point(30, 0, timeout_s=20)
                await gs.attitude_stream(10)
                await asyncio.sleep(1.5)
                await gs.stop_attitude_stream()

        watched.run(ground_station(), timeout=40)
        rows = page.get_by_test_id("traffic").locator(".tr")
        wait_for(lambda: rows.filter(has_text="#TPUD2rVER").count() > 0, what="the client's VER in the pane")
        assert page.get_by_test_id("horizon").get_attribute("data-state") == "live"
        assert float(page.get_by_test_id("yaw").inner_text()) == pytest.approx(30, abs=1.0)
        assert "udp 127.0.0.1:" in (page.get_by_test_id("link-banner").inner_text())
        page.get_by_test_id("panel-traffic").screenshot(path=str(artifacts / "console-watch-traffic.png"))
    finally:
        page.context.close()
    assert page_errors == [], page_errors
