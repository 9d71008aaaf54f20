"""A console with several cameras (issue 25): two simulators in this process, each addressed by
name under /cam/NAME/; pointing one moves only that one; the overview lists both with their state;
unknown names, the bound, names and the single-camera routes; the Host/Origin guard and the token
on the per-camera routes."""

from __future__ import annotations

import asyncio
import json
from collections.abc import AsyncIterator
from typing import Any

import aiohttp
import pytest

from topgimbal.cli.main import main as cli_main
from topgimbal.console import ConsoleServer
from topgimbal.console.cameras import (
    MAX_CAMERAS,
    CameraNameError,
    CameraSet,
    TooManyCamerasError,
    check_camera_name,
    local_plan,
)

from .conftest import eventually

pytestmark = pytest.mark.loopback


@pytest.fixture
async def two() -> AsyncIterator[ConsoleServer]:
    async with ConsoleServer(sims=["C12", "SIP"], port=0) as srv:
        yield srv


async def _json(http: aiohttp.ClientSession, url: str) -> tuple[int, Any]:
    async with http.get(url) as r:
        return r.status, await r.json(content_type=None)


async def _op(ws: aiohttp.ClientWebSocketResponse, op: str, **args: Any) -> dict[str, Any]:
    await ws.send_json({"op": op, "ref": op, **args})
    while True:
        msg = await ws.receive_json(timeout=60)
        if msg.get("ref") == op and msg["type"] in ("ack", "error"):
            return msg  # type: ignore[no-any-return]


async def test_pointing_one_camera_moves_only_that_one(two: ConsoleServer) -> None:
    sim1, sim2 = (two.cameras.get(n).sim for n in ("sim1", "sim2"))  # type: ignore[union-attr]
    assert sim1 is not None and sim2 is not None
    async with aiohttp.ClientSession() as http, http.ws_connect(two.base_url + "cam/sim2/ws") as ws:
        hello = await ws.receive_json(timeout=30)
        assert hello["type"] == "hello" and hello["model"]["name"] == "SIP"
        reply = await _op(ws, "point", yaw=30, pitch=-20)
        assert reply["type"] == "ack", reply
        await eventually(lambda: abs(sim2.gimbal.yaw_deg - 30) < 1 and abs(sim2.gimbal.pitch_deg + 20) < 1,
                         what="sim2 at yaw 30, pitch -20")  # fmt: skip
        assert sim1.gimbal.yaw_deg == 0.0 and sim1.gimbal.pitch_deg == 0.0
        # the first camera's page (/ws, the single-camera route) drives sim1 only
    async with aiohttp.ClientSession() as http, http.ws_connect(two.base_url + "ws") as ws:
        hello = await ws.receive_json(timeout=30)
        assert hello["model"]["name"] == "C12"
        assert (await _op(ws, "photo"))["type"] == "ack"
    assert sim1.camera.photos_taken == 1 and sim2.camera.photos_taken == 0


async def test_overview_lists_every_camera_with_its_state(two: ConsoleServer) -> None:
    async with aiohttp.ClientSession() as http:
        body: dict[str, Any] = {}

        async def fetch() -> None:
            nonlocal body
            status, body = await _json(http, two.base_url + "api/cameras")
            assert status == 200

        async def check() -> bool:
            await fetch()
            cams = body["cameras"]
            # recording is read once at start, so the grid knows it before any page asks
            return all(c["link"] == "up" and c["attitude"] is not None and c["recording"] is False for c in cams)

        loop = asyncio.get_running_loop()
        end = loop.time() + 30
        while not await check():
            assert loop.time() < end, body
            await asyncio.sleep(0.2)
        cams = {c["name"]: c for c in body["cameras"]}
        assert list(cams) == ["sim1", "sim2"]
        assert (cams["sim1"]["model"], cams["sim2"]["model"]) == ("C12", "SIP")
        assert {c["source"] for c in cams.values()} == {"sim"}
        assert body["max_cameras"] == MAX_CAMERAS and body["interval_s"] == 0.25
        # recording follows the camera: start it on sim2 through its page, the overview says so
        async with http.ws_connect(two.base_url + "cam/sim2/ws") as ws:
            await ws.receive_json(timeout=30)
            assert (await _op(ws, "record", action="start"))["type"] == "ack"
        _, body = await _json(http, two.base_url + "api/cameras")
        cams = {c["name"]: c for c in body["cameras"]}
        assert cams["sim2"]["recording"] is True and cams["sim1"]["recording"] is False
        assert cams["sim1"]["unavailable"] == {} == cams["sim2"]["unavailable"]


async def test_per_camera_routes_and_unknown_names(two: ConsoleServer) -> None:
    base = two.base_url
    async with aiohttp.ClientSession() as http:
        status, cat = await _json(http, base + "cam/sim2/api/catalog")
        assert status == 200 and cat["model"]["name"] == "SIP"
        status, cat = await _json(http, base + "api/catalog")  # the single-camera route: the first camera
        assert status == 200 and cat["model"]["name"] == "C12"
        status, st = await _json(http, base + "cam/sim1/api/status")
        assert status == 200 and st["type"] == "status"
        for path in ("cam/sim1/", "cam/sim2/static/app.js", "cam/sim2/static/lib/cameras.js"):
            async with http.get(base + path) as r:
                assert r.status == 200, path
        async with http.get(base + "cam/sim2", allow_redirects=False) as r:
            assert r.status == 302 and r.headers["Location"] == "/cam/sim2/"
        async with http.get(base + "cam/sim2/static/%2E%2E/server.py") as r:
            assert r.status == 404
        for path in ("cam/nope/api/status", "cam/nope/ws", "cam/nope/", "cam/bad%20name/api/catalog",
                     "cam/nope/api/video", "cam/nope/api/traffic.pcap"):  # fmt: skip
            status, body = await _json(http, base + path)
            assert status == 404, path
            assert body["cameras"] == ["sim1", "sim2"], body
            assert "sim1, sim2" in body["message"]
        async with http.get(base + "cam/sim1/api/traffic.pcap") as r:
            assert r.status == 200 and int(r.headers["X-Topgimbal-Frames"]) > 0


async def test_guard_and_token_on_per_camera_routes() -> None:
    async with ConsoleServer(sims=["C12", "C12"], port=0, token="s3cret") as srv:
        port = srv.bound_port
        base = srv.base_url
        async with aiohttp.ClientSession() as http:
            async with http.get(base + "cam/sim2/api/status", headers={"Host": f"evil.example:{port}"}) as r:
                assert r.status == 421
                assert "evil.example" in (await r.json())["message"]
            async with http.get(base + "cam/sim2/api/status") as r:
                assert r.status == 401
            async with http.get(base + "api/cameras") as r:
                assert r.status == 401
            async with http.get(base + "cam/sim2/api/status", params={"token": "s3cret"}) as r:
                assert r.status == 200
            with pytest.raises(aiohttp.WSServerHandshakeError) as err:
                async with http.ws_connect(
                    base + "cam/sim2/ws?token=s3cret", headers={"Origin": "http://evil.example"}
                ):
                    pass
            assert err.value.status == 403
            async with http.ws_connect(
                base + "cam/sim2/ws?token=s3cret", headers={"Origin": f"http://127.0.0.1:{port}"}
            ) as ws:
                assert (await ws.receive_json(timeout=30))["type"] == "hello"
            # a cross-site page's POST to a camera's video route is refused before anything runs
            async with http.post(base + "cam/sim2/api/video/zoom?token=s3cret", json={"direction": "in"},
                                 headers={"Origin": "http://evil.example"}) as r:  # fmt: skip
                assert r.status == 403
        sim2 = srv.cameras.get("sim2").sim  # type: ignore[union-attr]
        assert sim2 is not None and sim2.camera.digital_zoom_x == 1.0 and sim2.camera.zoom_dir == 0


def test_names_and_bounds() -> None:
    assert check_camera_name("left-1.a_b") == "left-1.a_b"
    for bad in ("", "-x", "a b", "a/b", "x" * 64, "é"):
        with pytest.raises(CameraNameError):
            check_camera_name(bad)
    plan = local_plan([("left", "udp://127.0.0.1:9", "C12"), ("sim1", "udp://127.0.0.1:8", "C12")], ["SIP", "C13"])
    assert [n for n, _, _ in plan] == ["left", "sim1", "sim2", "sim3"]
    assert plan[2] == ("sim2", None, "SIP")
    with pytest.raises(TooManyCamerasError, match=f"at most {MAX_CAMERAS}"):
        local_plan([], ["C12"] * (MAX_CAMERAS + 1))
    with pytest.raises(CameraNameError, match="twice"):
        local_plan([("a", "udp://127.0.0.1:9", "C12"), ("a", "udp://127.0.0.1:8", "C12")], [])
    cams = CameraSet(max_cameras=1)
    cams.check_room("one")
    assert cams.first is None and cams.names() == []


@pytest.mark.parametrize(
    ("argv", "needle"),
    [
        (["--camera", "a=udp://127.0.0.1:9,C12", "--camera", "a=udp://127.0.0.1:8,C12"], "twice"),
        (["--sim", "C12"] * (MAX_CAMERAS + 1), f"at most {MAX_CAMERAS}"),
        (["--camera", "a=udp://127.0.0.1:9,C12", "--url", "udp://127.0.0.1:5"], "--url"),
        (["--sim", "C12", "--sim", "C12", "--faults", "drop=0.1"], "--faults"),
        (["--zenoh", "nonsense"], "tcp/127.0.0.1:7447"),
    ],
)
def test_cli_refusals_exit_2(argv: list[str], needle: str, capsys: pytest.CaptureFixture[str]) -> None:
    assert cli_main(["console", "--port", "0", "--seconds", "0", *argv]) == 2
    err = capsys.readouterr().err
    assert needle in err, err


def test_cli_bad_camera_spec_is_a_usage_error(capsys: pytest.CaptureFixture[str]) -> None:
    with pytest.raises(SystemExit) as exit_:
        cli_main(["console", "--camera", "a b=udp://127.0.0.1:9,C12"])
    assert exit_.value.code == 2
    assert "NAME=URL,MODEL" in capsys.readouterr().err


def test_cameras_file(tmp_path: Any, capsys: pytest.CaptureFixture[str]) -> None:
    f = tmp_path / "cams.json"
    f.write_text(json.dumps([{"name": "a", "url": "udp://127.0.0.1:9", "model": "C12"}] * 2))
    assert cli_main(["console", "--port", "0", "--seconds", "0", "--cameras", str(f)]) == 2
    assert "twice" in capsys.readouterr().err


async def test_a_single_camera_console_says_it_has_no_switcher() -> None:
    async with ConsoleServer(sim_model="C12", port=0) as srv, aiohttp.ClientSession() as http:
        status, body = await _json(http, srv.base_url + "api/cameras")
        assert status == 200 and body["several"] is False and body["cameras"] == []
        async with http.get(srv.base_url + "cam/sim1/api/status") as r:
            assert r.status == 404  # the per-camera routes are for a console of several cameras
