"""Several cameras in Debian's chromium (issue 25): the overview grid lists every camera with its
model, link, attitude and recording; a click on a tile opens that camera's page (its own controls,
telemetry and switcher selection); pointing there moves that camera only; a camera reached through
`topgimbal zenoh` says its traffic is unavailable and why, with no error on the page.

Screenshot: test-artifacts/issue25-console-grid.png (docs/images/issue25/ has a copy)."""

from __future__ import annotations

import signal
import subprocess
import sys
import urllib.error
import urllib.request
from pathlib import Path
from typing import Any

import pytest

from topgimbal.console import ConsoleServer
from topgimbal.console.remote_hub import NOT_CARRIED
from topgimbal.sim import Simulator

from .conftest import BackgroundConsole, wait_for, wait_for_testid
from .test_multi_zenoh import free_port

pytestmark = [pytest.mark.external, pytest.mark.browser, pytest.mark.integration]


class Several(BackgroundConsole):
    """Two simulators in the console's process and a third camera served by `topgimbal zenoh`."""

    def __enter__(self) -> Several:
        self.thread.start()
        self.far = Simulator("C13")
        self.run(self.far.start(udp=[("127.0.0.1", 0)]))
        port = free_port()
        self.proc = subprocess.Popen(
            [sys.executable, "-m", "topgimbal.cli.main", "zenoh", "--listen", f"tcp/127.0.0.1:{port}",
             "--camera", f"far={self.far.url},C13"],
            stdout=subprocess.PIPE, stderr=subprocess.DEVNULL,
            preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_DFL),
        )  # fmt: skip
        assert self.proc.stdout is not None and b"serving" in self.proc.stdout.readline()
        self.server = ConsoleServer(sims=["C12", "SIP"], zenoh=[f"tcp/127.0.0.1:{port}"], port=0)
        self.run(self.server.start())
        return self

    def __exit__(self, *exc: object) -> None:
        self.proc.send_signal(signal.SIGINT)
        try:
            self.proc.wait(30)
        except subprocess.TimeoutExpired:
            self.proc.kill()
            self.proc.wait()
        self.run(self.far.stop())
        super().__exit__(*exc)

    def sim_of(self, name: str) -> Any:
        assert self.server is not None
        cam = self.server.cameras.get(name)
        assert cam is not None
        return cam.sim


def test_grid_and_switcher(browser: Any, artifacts: Path, page_errors: list[str]) -> None:
    with Several("C12") as bg:
        context = browser.new_context(viewport={"width": 1400, "height": 1000})
        page = context.new_page()
        page.on("pageerror", lambda e: page_errors.append(str(e)))
        page.on("console", lambda m: page_errors.append(m.text) if m.type == "error" else None)
        try:
            page.goto(bg.url)
            page.wait_for_selector("body[data-ready='1']", timeout=30_000)
            grid = page.get_by_test_id("camera-grid")
            for name in ("sim1", "sim2", "far"):
                page.wait_for_selector(f"[data-testid=cam-tile-{name}][data-link=up]", timeout=30_000)
            assert page.get_by_test_id("cam-tile-sim1").get_attribute("aria-current") == "true"
            assert "SIP" in page.get_by_test_id("cam-tile-sim2").inner_text()
            far = page.get_by_test_id("cam-tile-far").inner_text()
            assert "C13" in far and "zenoh" in far and "no attitude" in far and "traffic: unavailable" in far
            assert page.get_by_test_id("cam-unavailable-far-traffic").get_attribute("title") == NOT_CARRIED
            assert page.get_by_test_id("camera-select").input_value() == "sim1"

            # the switcher: a click on sim2's tile opens its page, with the SIP's controls
            page.get_by_test_id("cam-tile-sim2").click()
            page.wait_for_url("**/cam/sim2/", timeout=30_000)
            page.wait_for_selector("body[data-ready='1']", timeout=30_000)
            assert "SIP" in page.get_by_test_id("model").inner_text()
            wait_for(lambda: page.get_by_test_id("camera-select").input_value() == "sim2", 30, what="sim2 selected")
            page.get_by_test_id("angle-yaw").fill("30")
            page.get_by_test_id("angle-pitch").fill("-20")
            page.get_by_test_id("btn-point").click()
            sim1, sim2 = bg.sim_of("sim1"), bg.sim_of("sim2")
            wait_for(lambda: bg.call(lambda: abs(sim2.gimbal.yaw_deg - 30) < 1), 60, what="sim2 at yaw 30")
            assert bg.call(lambda: (sim1.gimbal.yaw_deg, sim1.gimbal.pitch_deg)) == (0.0, 0.0)
            wait_for_testid(page, "cam-att-sim2", "Math.abs(Number(e.dataset.yaw) - 30) < 1")
            assert grid.is_visible()
            grid_shot = artifacts / "issue25-console-grid.png"
            page.get_by_test_id("panel-cameras").screenshot(path=str(grid_shot))
            page.screenshot(path=str(artifacts / "issue25-console-sim2.png"))

            # the Zenoh camera's page: traffic unavailable with the reason, not an error
            page.get_by_test_id("camera-select").select_option("far")
            page.wait_for_url("**/cam/far/", timeout=30_000)
            page.wait_for_selector("body[data-ready='1']", timeout=30_000)
            reason = page.get_by_test_id("traffic-reason")
            assert reason.is_visible() and NOT_CARRIED in reason.inner_text()
            assert page.get_by_test_id("traffic-pcap").get_attribute("href") is None
            # ... and seen to be disabled; the server gives no (empty) pcap for it either (issue 35.6)
            pcap = page.get_by_test_id("traffic-pcap")
            assert pcap.get_attribute("aria-disabled") == "true"
            assert pcap.evaluate("(e) => getComputedStyle(e).pointerEvents") == "none"
            try:
                urllib.request.urlopen(page.url.split("?")[0] + "api/traffic.pcap", timeout=20)
                raise AssertionError("a pcap was served for a Zenoh camera")
            except urllib.error.HTTPError as exc:
                assert exc.code == 409 and "no pcap" in exc.read().decode()
            assert page.get_by_test_id("toasts").inner_text().strip() == ""
        finally:
            context.close()
    assert page_errors == [], page_errors


def test_a_press_held_while_its_tile_changes_is_still_a_click(browser: Any, page_errors: list[str]) -> None:
    """The grid's tiles change with every attitude sample: a press on a tile's text, released after
    the text changed, opens that camera's page (the parts are updated in place, not replaced)."""
    with Several("C12") as bg:
        context = browser.new_context(viewport={"width": 1400, "height": 1000})
        page = context.new_page()
        page.on("pageerror", lambda e: page_errors.append(str(e)))
        try:
            page.goto(bg.url)
            page.wait_for_selector("body[data-ready='1']", timeout=30_000)
            page.wait_for_selector("[data-testid=cam-tile-sim2][data-link=up]", timeout=30_000)
            att = page.get_by_test_id("cam-att-sim2")
            wait_for(lambda: "yaw" in att.inner_text(), 30, what="sim2's attitude on its tile")
            box = att.bounding_box()
            assert box is not None
            page.mouse.move(box["x"] + box["width"] / 2, box["y"] + box["height"] / 2)
            page.mouse.down()
            before = att.inner_text()
            sim2 = bg.sim_of("sim2")
            bg.call(lambda: setattr(sim2.gimbal.yaw_axis, "pos", 25.0))  # the camera turns meanwhile
            wait_for(lambda: att.inner_text() != before, 30, what="the tile's text changed under the press")
            page.mouse.up()
            page.wait_for_url("**/cam/sim2/", timeout=30_000)
        finally:
            context.close()
