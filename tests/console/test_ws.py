"""The WebSocket protocol and the catalog API, against an in-process simulator (no browser)."""

from __future__ import annotations

import asyncio
import time
from collections.abc import AsyncIterator
from typing import Any

import aiohttp
import pytest

from topgimbal.console import ConsoleServer
from waiting import SETTLED_DEG, near

pytestmark = pytest.mark.loopback


@pytest.fixture
async def console() -> AsyncIterator[ConsoleServer]:
    async with ConsoleServer(sim_model="C12", port=0) as srv:
        yield srv


class Page:
    """A scripted page: sends ops, collects pushes."""

    def __init__(self, ws: aiohttp.ClientWebSocketResponse) -> None:
        self.ws = ws
        self.ref = 0
        self.pushes: list[dict[str, Any]] = []

    async def op(self, op: str, timeout: float = 10.0, **args: Any) -> dict[str, Any]:
        self.ref += 1
        ref = self.ref
        await self.ws.send_json({"op": op, "ref": ref, **args})
        deadline = time.monotonic() + timeout
        while time.monotonic() < deadline:
            msg = await self.ws.receive_json(timeout=max(0.01, deadline - time.monotonic()))
            if msg.get("ref") == ref and msg["type"] in ("ack", "error"):
                return msg  # type: ignore[no-any-return]
            self.pushes.append(msg)
        raise AssertionError(f"no reply to {op}")

    async def collect(self, seconds: float) -> list[dict[str, Any]]:
        end = time.monotonic() + seconds
        while (left := end - time.monotonic()) > 0:
            try:
                self.pushes.append(await self.ws.receive_json(timeout=left))
            except asyncio.TimeoutError:
                break
        return self.pushes


async def _page(http: aiohttp.ClientSession, srv: ConsoleServer) -> Page:
    ws = await http.ws_connect(srv.base_url + "ws")
    p = Page(ws)
    hello = await ws.receive_json(timeout=30)
    assert hello["type"] == "hello"
    assert hello["model"]["name"] == "C12"
    assert hello["dialect"] == "skydroid"
    return p


async def test_catalog_carries_field_metadata(console: ConsoleServer) -> None:
    async with aiohttp.ClientSession() as http, http.get(console.base_url + "api/catalog") as r:
        cat = await r.json()
    assert cat["model"]["name"] == "C12" and cat["model"]["thermal"] is True
    gay = cat["commands"]["GAY"]
    yaw = next(f for f in gay["forms"][0]["fields"] if f["name"] == "yaw_deg")
    assert (yaw["min"], yaw["max"], yaw["unit"], yaw["step"]) == (-90, 90, "deg", 0.01)
    img = cat["commands"]["IMG"]
    palette = img["forms"][0]["fields"][0]
    assert palette["kind"] == "enum"
    assert {"white_hot", "black_hot"} <= {v["name"] for v in palette["values"]}
    # C13-only thermal settings are listed as unsupported, with the reason
    assert "TSM" not in cat["commands"]
    assert "C12 does not support TSM" in cat["unsupported"]["TSM"]["reason"]
    assert "C13" in cat["unsupported"]["TSM"]["reason"]


async def test_ops_are_acked_and_act_on_the_camera(console: ConsoleServer) -> None:
    sim = console.sim
    async with aiohttp.ClientSession() as http:
        page = await _page(http, console)
        before = sim.camera.photos_taken
        ack = await page.op("photo")
        assert ack["type"] == "ack", ack
        assert sim.camera.photos_taken == before + 1

        ack = await page.op("request", id="VER", read=True)
        assert ack["type"] == "ack"
        assert ack["result"]["id"] == "VER" and ack["result"]["fields"]["version"]

        ack = await page.op("record", action="start")
        assert ack["type"] == "ack" and sim.camera.recording is True
        status = await page.op("status")
        assert status["result"]["recording"] is True and status["result"]["recording_since"] > 0
        ack = await page.op("record", action="stop")
        assert ack["type"] == "ack" and sim.camera.recording is False

        ack = await page.op("sd")
        assert ack["type"] == "ack"
        assert ack["result"]["present"] is True and ack["result"]["total_mb"] > 0

        ack = await page.op("point", yaw=12.5, pitch=-8)
        assert ack["type"] == "ack"
        # the live axes settle on the target (tests/waiting.py: a failure shows where they were)
        await near("the simulator's yaw", lambda: sim.gimbal.yaw_deg, 12.5, margin=SETTLED_DEG, bound_s=30)
        await near("the simulator's pitch", lambda: sim.gimbal.pitch_deg, -8, margin=SETTLED_DEG, bound_s=30)

        raw = await page.op("raw", frame="#TPUD2rVER0051")
        assert raw["type"] == "ack", raw
        assert raw["result"]["id"] == "VER" and raw["result"]["fields"]["version"]
        # without its checksum the frame is completed (as the CLI's raw does), never corrected
        raw = await page.op("raw", frame="#TPUD2rVER00")
        assert raw["type"] == "ack" and raw["result"]["sent"] == "#TPUD2rVER0051", raw
        raw = await page.op("raw", frame="#TPUD2rVER0052")
        assert raw["type"] == "error" and raw["kind"] == "frame" and "51" in raw["message"], raw
        await page.ws.close()


async def test_errors_are_readable(console: ConsoleServer) -> None:
    async with aiohttp.ClientSession() as http:
        page = await _page(http, console)
        err = await page.op("point", yaw=200, pitch=0)
        assert err["type"] == "error" and err["kind"] == "value"
        assert "yaw" in err["message"] and "90" in err["message"]

        err = await page.op("request", id="TSM", values={"scene": "general"})
        assert err["type"] == "error" and err["kind"] == "unsupported"
        assert "C12" in err["message"] and "TSM" in err["message"]

        err = await page.op("request", id="XYZ")
        assert err["type"] == "error" and "XYZ" in err["message"]

        err = await page.op("request", id="IMG", values={"palette": "purple"})
        assert err["type"] == "error" and "palette" in err["message"] and "white_hot" in err["message"]

        err = await page.op("raw", frame="#TPUD2rVER00ZZ")
        assert err["type"] == "error" and err["kind"] == "frame"

        err = await page.op("fly")
        assert err["type"] == "error" and "unknown op" in err["message"]

        err = await page.op("set_network", values={"ip": "127.0.0.9"})
        assert err["type"] == "error" and "confirm" in err["message"]

        await page.ws.send_str("not json")
        msg = await page.ws.receive_json(timeout=30)
        while msg["type"] != "error":
            msg = await page.ws.receive_json(timeout=30)
        assert "JSON" in msg["message"]
        await page.ws.close()


async def test_pushes_attitude_status_and_traffic(console: ConsoleServer) -> None:
    async with aiohttp.ClientSession() as http:
        page = await _page(http, console)
        await page.op("photo")
        pushes = await page.collect(1.5)
        kinds = {m["type"] for m in pushes}
        assert {"attitude", "status", "traffic"} <= kinds
        att = [m for m in pushes if m["type"] == "attitude"]
        assert all({"yaw", "pitch", "roll"} <= m.keys() for m in att)
        # throttled: never more than 50 a second (1.5 s of collecting, plus the op's wait)
        assert 0 < len(att) <= 50 * 3
        items = [i for m in pushes if m["type"] == "traffic" for i in m["items"]]
        dirs = {i["dir"] for i in items}
        assert dirs == {"in", "out"}
        cap = [i for i in items if i["id"] == "CAP"]
        assert cap and all(i["frame"].startswith("#") for i in cap)
        status = [m for m in pushes if m["type"] == "status"][-1]
        assert status["link"] == "up"
        assert status["stats"]["frames_in"] > 0 and status["stats"]["frames_out"] > 0
        await page.ws.close()


async def test_attitude_push_rate_is_capped() -> None:
    async with ConsoleServer(sim_model="C12", port=0, attitude_hz=10) as srv, aiohttp.ClientSession() as http:
        page = await _page(http, srv)
        await page.collect(0.5)  # let the stream start
        page.pushes.clear()
        t0 = time.monotonic()
        pushes = await page.collect(2.0)
        elapsed = time.monotonic() - t0
        n = sum(1 for m in pushes if m["type"] == "attitude")
        assert 0 < n <= 10 * elapsed + 2
        await page.ws.close()


async def test_two_pages_share_one_camera(console: ConsoleServer) -> None:
    async with aiohttp.ClientSession() as http:
        a = await _page(http, console)
        b = await _page(http, console)
        ack = await a.op("center")
        assert ack["type"] == "ack"
        pushes = await b.collect(0.8)
        items = [i for m in pushes if m["type"] == "traffic" for i in m["items"]]
        assert any(i["id"] == "PTZ" and i["dir"] == "out" for i in items)
        await a.ws.close()
        await b.ws.close()


async def test_recording_started_elsewhere_shows_up(console: ConsoleServer) -> None:
    async with aiohttp.ClientSession() as http:
        page = await _page(http, console)
        status = await page.op("status")
        assert status["result"]["recording"] in (None, False)
        await console.cam.start_recording()  # through the client directly, not by a page op
        status = await page.op("status")
        assert status["result"]["recording"] is True
        assert status["result"]["recording_since"] is not None
        await console.cam.stop_recording()
        status = await page.op("status")
        assert status["result"]["recording"] is False and status["result"]["recording_since"] is None
        await page.ws.close()
