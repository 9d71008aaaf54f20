"""The console follows the cameras of a `topgimbal zenoh` process (issue 25): three simulators
behind `topgimbal zenoh` (its own process, scouting off, loopback endpoints); the console finds them
by their liveliness tokens, shows each in the overview, points one through its per-camera API while
the others stay still, says traffic is unavailable for them (not an error), marks them LOST when
the server goes away and shows them again when it comes back."""

from __future__ import annotations

import asyncio
import logging
import signal
import socket
import sys
from typing import Any

import aiohttp
import pytest

from topgimbal.console import ConsoleServer
from topgimbal.console.remote_hub import NOT_CARRIED
from topgimbal.sim import Simulator

from .conftest import eventually


def free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return int(s.getsockname()[1])


pytestmark = [pytest.mark.loopback, pytest.mark.integration]

NAMES = ["north", "east", "south"]


async def _serve(args: list[str]) -> asyncio.subprocess.Process:
    proc = await asyncio.create_subprocess_exec(
        sys.executable, "-m", "topgimbal.cli.main", "zenoh", *args,
        stdout=asyncio.subprocess.PIPE, stderr=asyncio.subprocess.PIPE,
        preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_DFL),
    )  # fmt: skip
    assert proc.stdout is not None
    line = await asyncio.wait_for(proc.stdout.readline(), 60)
    assert b"serving" in line, line + (await proc.stderr.read() if proc.stderr else b"")
    return proc


async def _stop(proc: asyncio.subprocess.Process) -> None:
    if proc.returncode is None:
        proc.send_signal(signal.SIGINT)
        try:
            await asyncio.wait_for(proc.wait(), 30)
        except asyncio.TimeoutError:
            proc.kill()
            await proc.wait()


async def _op(ws: aiohttp.ClientWebSocketResponse, op: str, **args: Any) -> dict[str, Any]:
    await ws.send_json({"op": op, "ref": op, **args})
    while True:
        msg = await ws.receive_json(timeout=120)
        if msg.get("ref") == op and msg["type"] in ("ack", "error"):
            return msg  # type: ignore[no-any-return]


async def test_console_follows_the_cameras_of_a_zenoh_server() -> None:
    sims = []
    for _ in NAMES:
        sim = Simulator("C12")
        await sim.start(udp=[("127.0.0.1", 0)])
        sims.append(sim)
    port = free_port()
    args = ["--listen", f"tcp/127.0.0.1:{port}"]
    for name, sim in zip(NAMES, sims, strict=True):
        args += ["--camera", f"{name}={sim.url},C12"]
    proc = await _serve(args)
    console = ConsoleServer(zenoh=[f"tcp/127.0.0.1:{port}"], port=0)
    try:
        await console.start()
        overview: dict[str, dict[str, Any]] = {}
        async with aiohttp.ClientSession() as http:

            async def refresh() -> None:
                async with http.get(console.base_url + "api/cameras") as r:
                    assert r.status == 200
                    overview.clear()
                    overview.update({c["name"]: c for c in (await r.json())["cameras"]})

            async def until(check: Any, what: str, timeout: float = 60) -> None:
                loop = asyncio.get_running_loop()
                end = loop.time() + timeout
                while True:
                    await refresh()
                    if check():
                        return
                    assert loop.time() < end, f"{what}: {overview}"
                    await asyncio.sleep(0.2)

            await until(lambda: sorted(overview) == sorted(NAMES) and all(
                c["link"] == "up" and c["attitude"] is not None for c in overview.values()), "three cameras up")  # fmt: skip
            await until(lambda: all(c["recording"] is False for c in overview.values()), "recording read once")
            for c in overview.values():
                assert c["source"] == "zenoh" and c["model"] == "C12"
                assert c["unavailable"]["traffic"] == NOT_CARRIED

            async with http.ws_connect(console.base_url + "cam/east/ws") as ws:
                hello = await ws.receive_json(timeout=30)
                assert hello["type"] == "hello" and hello["unavailable"]["traffic"] == NOT_CARRIED
                assert hello["url"].startswith("zenoh/east?")
                reply = await _op(ws, "point", yaw=25, pitch=-30)
                assert reply["type"] == "ack", reply
                east = sims[1].gimbal
                await eventually(lambda: abs(east.yaw_deg - 25) <= 1 and abs(east.pitch_deg + 30) <= 1, 60,
                                 "east at yaw 25, pitch -30")  # fmt: skip
                for still in (sims[0], sims[2]):
                    assert still.gimbal.yaw_deg == 0.0 and still.gimbal.pitch_deg == 0.0
                # a refusal comes back as the SDK's kind, not as a console error
                refused = await _op(ws, "point", yaw=500)
                assert refused["type"] == "error" and refused["kind"] == "value", refused
            await until(lambda: abs(overview["east"]["attitude"]["yaw"] - 25) <= 1, "east's attitude in the grid")
            assert overview["north"]["attitude"]["yaw"] == 0.0 and overview["south"]["attitude"]["yaw"] == 0.0
            async with http.get(console.base_url + "cam/west/api/status") as r:
                assert r.status == 404 and sorted((await r.json())["cameras"]) == sorted(NAMES)

            # the server goes away: every camera LOST, with the reason; it comes back: up again
            await _stop(proc)
            await until(lambda: all(c["link"] == "lost" and "no longer served" in c["link_reason"]
                                    for c in overview.values()), "three cameras lost")  # fmt: skip
            proc = await _serve(args)
            await until(lambda: len(overview) == 3 and all(c["link"] == "up" for c in overview.values()),
                        "three cameras back", timeout=90)  # fmt: skip
    finally:
        await console.stop()
        await _stop(proc)
        for sim in sims:
            await sim.stop()


async def test_unreachable_zenoh_endpoint_is_a_clear_error() -> None:
    console = ConsoleServer(zenoh=[f"tcp/127.0.0.1:{free_port()}"], port=0)
    with pytest.raises(Exception, match="cannot open a Zenoh session"):
        await console.start()
    assert console.zenoh is None and len(console.cameras) == 0


async def test_zenoh_cameras_are_bounded_and_odd_tokens_ignored(caplog: pytest.LogCaptureFixture) -> None:
    """At the console's bound a newcomer is left out with a warning; a camera no longer served
    makes room for a new one; a token nobody answers for, or not of the fleet's layout, shows nothing."""
    import json

    import zenoh

    caplog.set_level(logging.DEBUG, logger="topgimbal.console")
    sims = []
    for _ in range(3):
        sim = Simulator("C12")
        await sim.start(udp=[("127.0.0.1", 0)])
        sims.append(sim)
    port = free_port()

    def serving(names: list[str]) -> list[str]:
        args = ["--listen", f"tcp/127.0.0.1:{port}"]
        for name, sim in zip(names, sims, strict=False):
            args += ["--camera", f"{name}={sim.url},C12"]
        return args

    proc = await _serve(serving(["north", "east"]))
    conf = zenoh.Config()
    for k, v in (("mode", "client"), ("scouting/multicast/enabled", False), ("scouting/gossip/enabled", False),
                 ("connect/endpoints", [f"tcp/127.0.0.1:{port}"])):  # fmt: skip
        conf.insert_json5(k, json.dumps(v))
    raw = await asyncio.to_thread(zenoh.open, conf)
    console = ConsoleServer(zenoh=[f"tcp/127.0.0.1:{port}"], port=0)
    console.cameras.max_cameras = 1
    try:
        tokens = [raw.liveliness().declare_token(k) for k in ("topgimbal/ghost", "topgimbal/x/y")]
        await console.start()
        await eventually(lambda: len(console.cameras) == 1, 60, "one camera shown")
        await eventually(lambda: "this console shows at most 1 cameras" in caplog.text, 60, "the bound's warning")
        await eventually(lambda: "'ghost' on Zenoh could not be opened" in caplog.text, 60, "the ghost's warning")
        assert console.cameras.names()[0] in ("north", "east") and console.zenoh is not None
        assert console.zenoh.left_out >= 1
        for t in tokens:
            t.undeclare()
        first = console.cameras.names()[0]
        # the server goes; another serves "west": the camera no longer served makes room for it
        await _stop(proc)
        await eventually(lambda: not console.cameras.get(first).served, 60, "the first camera gone")  # type: ignore[union-attr]
        proc = await _serve(serving(["west"]))
        await eventually(lambda: console.cameras.names() == ["west"], 90, "west in place of the gone camera")
        assert "makes room for west" in caplog.text
        assert "Traceback" not in caplog.text
    finally:
        await console.stop()
        await asyncio.to_thread(raw.close)
        await _stop(proc)
        for sim in sims:
            await sim.stop()
