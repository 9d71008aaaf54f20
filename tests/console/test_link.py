"""Issue 17 item 3 over the WebSocket: a camera that goes silent is LOST within a few seconds (UDP
included), with the reason and since when, from the client's own link-loss detection; the state
clears by itself when frames come back. No browser here (test_browser_link.py has the page)."""

from __future__ import annotations

import asyncio
import time
from collections.abc import Callable
from typing import Any

import aiohttp
import pytest

from topgimbal.console import ConsoleServer
from topgimbal.sim import FaultPlan, Simulator

pytestmark = [pytest.mark.loopback, pytest.mark.integration]


async def next_status(
    ws: aiohttp.ClientWebSocketResponse, pred: Callable[[dict[str, Any]], bool], timeout: float, seen: list[Any]
) -> dict[str, Any]:
    """The first status push satisfying `pred`; every push on the way goes to `seen`."""
    deadline = time.monotonic() + timeout
    while (left := deadline - time.monotonic()) > 0:
        try:
            msg = await ws.receive_json(timeout=left)
        except asyncio.TimeoutError:
            break
        seen.append(msg)
        if msg.get("type") == "status" and pred(msg):
            return msg
    states = [m.get("link") for m in seen if m.get("type") == "status"][-5:]
    raise AssertionError(f"no matching status within {timeout} s (last link states: {states})")


def lost(st: dict[str, Any]) -> bool:
    return bool(st["link"] == "lost")


def up(st: dict[str, Any]) -> bool:
    return bool(st["link"] == "up")


async def test_a_silent_udp_camera_is_lost_and_comes_back_by_itself() -> None:
    async with ConsoleServer(sim_model="C12", port=0) as srv, aiohttp.ClientSession() as http:
        assert srv.sim is not None and srv.cam is not None
        ws = await http.ws_connect(srv.base_url + "ws")
        seen: list[Any] = []
        await next_status(ws, up, 10, seen)
        port = srv.sim.addresses["udp"][0][1]
        await srv.sim.stop()  # UDP: nothing tells the console; only silence
        stopped = time.time()
        st = await next_status(ws, lost, 15, seen)
        assert "nothing heard from the device" in st["link_reason"]
        assert st["lost_since"] is not None and st["lost_since"] >= stopped
        assert st["last_in"] is not None and st["last_in"] <= st["lost_since"]
        assert srv.cam.link_state["up"] is False  # the console's state is the client's
        assert st["stats"]["link_losses"] >= 1
        # while lost, the LOST state is the message: no toast per background job on top of it
        quiet_from = len(seen)
        await asyncio.sleep(4.0)
        await next_status(ws, lost, 5, seen)
        assert [m for m in seen[quiet_from:] if m.get("type") == "error"] == []
        await srv.sim.start(udp=[("127.0.0.1", port)])
        back = await next_status(ws, up, 20, seen)
        assert back["lost_since"] is None and back["link_reason"] == ""
        assert srv.cam.link_state["up"] is True
        # and the camera answers ops again
        await ws.send_json({"op": "photo", "ref": 1})
        while (reply := await ws.receive_json(timeout=30)).get("ref") != 1:
            pass
        assert reply["type"] == "ack", reply


async def test_a_camera_without_a_stream_is_lost_in_a_fault_plan_silence() -> None:
    """The C13 sends no attitude stream: the console's link check keeps the client expecting an
    answer, so the silence is noticed; the simulator's fault plan silences it from 3 s to 12 s."""
    plan = FaultPlan(silence=((3.0, 12.0),))
    async with ConsoleServer(sim_model="C13", sim_faults=plan, port=0) as srv, aiohttp.ClientSession() as http:
        ws = await http.ws_connect(srv.base_url + "ws")
        seen: list[Any] = []
        st = await next_status(ws, lost, 20, seen)
        assert st["link_reason"] and st["lost_since"] is not None
        await next_status(ws, up, 25, seen)
        assert srv.sim is not None and srv.sim.fault_counts["out"]  # the plan did silence it


async def test_a_closed_tcp_link_is_lost_and_reconnects() -> None:
    sim = Simulator(model="C12")
    await sim.start(tcp=[("127.0.0.1", 0)])
    port = sim.addresses["tcp"][0][1]
    try:
        async with (
            ConsoleServer(url=f"tcp://127.0.0.1:{port}", model="C12", port=0) as srv,
            aiohttp.ClientSession() as http,
        ):
            ws = await http.ws_connect(srv.base_url + "ws")
            seen: list[Any] = []
            await next_status(ws, up, 10, seen)
            await sim.stop()
            st = await next_status(ws, lost, 10, seen)
            assert st["link_reason"]
            await sim.start(tcp=[("127.0.0.1", port)])
            await next_status(ws, up, 20, seen)
    finally:
        await sim.stop()


async def test_the_link_state_is_pushed_at_once() -> None:
    """A change is pushed when the client reports it, not only with the periodic status."""
    async with ConsoleServer(sim_model="C12", port=0) as srv, aiohttp.ClientSession() as http:
        assert srv.hub is not None and srv.sim is not None
        srv.hub.status_interval_s = 3600.0  # no periodic pushes from now on (after the next)
        ws = await http.ws_connect(srv.base_url + "ws")
        seen: list[Any] = []
        await asyncio.sleep(1.0)
        await srv.sim.stop()
        st = await next_status(ws, lost, 15, seen)
        assert st["lost_since"] is not None
