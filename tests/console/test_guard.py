"""The Host/Origin allow-list (issue 9): DNS rebinding and cross-site sockets are refused on
every route, even on loopback without a token; the console's own names and --allow-host pass."""

from __future__ import annotations

import asyncio
import logging
from collections.abc import AsyncIterator
from typing import Any

import aiohttp
import pytest
from aiohttp.test_utils import make_mocked_request

from topgimbal.cli.console_cmd import build_server
from topgimbal.cli.main import build_parser
from topgimbal.console import ConsoleServer
from topgimbal.console.guard import (
    HostGuard,
    HostNameError,
    check_allow_host,
    default_allowed_hosts,
    split_host_port,
)

pytestmark = pytest.mark.loopback

ROUTES = ("", "static/app.js", "static/lib/conn.js", "api/status", "api/catalog", "ws")


@pytest.fixture
async def console() -> AsyncIterator[ConsoleServer]:
    async with ConsoleServer(sim_model="C12", port=0, allow_hosts=["camera-bench.example"]) as srv:
        yield srv


def _port(srv: ConsoleServer) -> int:
    assert srv.bound_port
    return srv.bound_port


async def _raw_get(port: int, request: bytes) -> tuple[int, bytes]:
    """Send a hand-written HTTP request (any Host, or none) and return (status, body)."""
    reader, writer = await asyncio.open_connection("127.0.0.1", port)
    try:
        writer.write(request)
        await writer.drain()
        data = await asyncio.wait_for(reader.read(), 10)
    finally:
        writer.close()
    head, _, body = data.partition(b"\r\n\r\n")
    return int(head.split(b" ", 2)[1]), body


async def test_dns_rebinding_host_is_refused_on_every_route(console: ConsoleServer) -> None:
    port = _port(console)
    async with aiohttp.ClientSession() as http:
        for path in ROUTES:
            for host in (f"evil.example:{port}", f"localhost.evil.example:{port}", f"127.0.0.1.nip.io:{port}"):
                async with http.get(console.base_url + path, headers={"Host": host}) as r:
                    assert r.status == 421, (path, host)
                    body = await r.json()
                    assert "DNS-rebinding" in body["message"] and "--allow-host" in body["message"], body
                    assert host.split(":")[0] in body["message"]


@pytest.mark.parametrize(
    "request_text",
    [
        b"GET /api/status HTTP/1.0\r\n\r\n",  # no Host at all
        b"GET /api/status HTTP/1.1\r\nHost: 127.0.0.1:1\r\nConnection: close\r\n\r\n",  # another port
        b"GET /api/status HTTP/1.1\r\nHost: evil.example\r\nConnection: close\r\n\r\n",
        b"GET / HTTP/1.1\r\nHost: 127.0.0.1@evil.example\r\nConnection: close\r\n\r\n",
        b"GET / HTTP/1.1\r\nHost: ::1\r\nConnection: close\r\n\r\n",  # IPv6 without brackets
    ],
)
async def test_raw_requests_with_bad_hosts_are_refused(console: ConsoleServer, request_text: bytes) -> None:
    status, body = await _raw_get(_port(console), request_text)
    assert status == 421, body
    assert b"Host" in body


async def test_own_names_are_answered(console: ConsoleServer) -> None:
    port = _port(console)
    async with aiohttp.ClientSession() as http:
        for host in (
            f"127.0.0.1:{port}",
            f"localhost:{port}",
            f"LOCALHOST:{port}",
            f"localhost.:{port}",
            f"[::1]:{port}",
            f"camera-bench.example:{port}",  # --allow-host
        ):
            for path in ROUTES[:-1]:
                async with http.get(console.base_url + path, headers={"Host": host}) as r:
                    assert r.status == 200, (host, path)
    status, body = await _raw_get(
        port, f"GET /api/status HTTP/1.1\r\nHost: localhost:{port}\r\nConnection: close\r\n\r\n".encode()
    )
    assert status == 200 and b'"link"' in body


async def test_rebinding_websocket_cannot_take_a_photo(console: ConsoleServer) -> None:
    """The attack of issue 9: Host and Origin both evil.example; refused, and nothing happens."""
    port = _port(console)
    before = console.sim.camera.photos_taken
    async with aiohttp.ClientSession() as http:
        with pytest.raises(aiohttp.WSServerHandshakeError) as exc:
            async with http.ws_connect(
                console.base_url + "ws",
                headers={"Host": f"evil.example:{port}", "Origin": f"http://evil.example:{port}"},
            ) as ws:
                await ws.send_json({"op": "photo", "ref": 1})
        assert exc.value.status == 421
    await asyncio.sleep(0.3)
    assert console.sim.camera.photos_taken == before


@pytest.mark.parametrize(
    "origin",
    [
        "http://evil.example:{port}",
        "ws://127.0.0.1:{port}",
        "wss://127.0.0.1:{port}",
        "javascript:alert(1)",
        "null",
        "",
        "file://",
        "http://127.0.0.1:{other}",
        "http://127.0.0.1",
        "https://127.0.0.1",
        "http://127.0.0.1:{port}/ws",
        "http://user@127.0.0.1:{port}",
        "http://127.0.0.1:{port}.evil.example",
        "HTTP://127.0.0.1:{port}",
    ],
)
async def test_foreign_origins_are_refused_on_the_websocket(console: ConsoleServer, origin: str) -> None:
    port = _port(console)
    value = origin.format(port=port, other=port + 1 if port < 65535 else port - 1)
    async with aiohttp.ClientSession() as http:
        with pytest.raises(aiohttp.WSServerHandshakeError) as exc:
            async with http.ws_connect(console.base_url + "ws", headers={"Origin": value}):
                pass
        assert exc.value.status == 403, value
        async with http.get(console.base_url + "ws", headers={"Origin": value}) as r:
            assert r.status == 403
            message = (await r.json())["message"]
            assert "Origin" in message and "expected http(s)://NAME:PORT" in message


@pytest.mark.parametrize("name", ["127.0.0.1", "localhost", "[::1]", "camera-bench.example"])
async def test_own_origins_open_the_websocket(console: ConsoleServer, name: str) -> None:
    origin = f"http://{name}:{_port(console)}"
    async with (
        aiohttp.ClientSession() as http,
        http.ws_connect(console.base_url + "ws", headers={"Origin": origin}) as ws,
    ):
        assert (await ws.receive_json(timeout=30))["type"] == "hello"


async def test_state_changing_http_requests_need_an_own_origin(console: ConsoleServer) -> None:
    port = _port(console)
    async with aiohttp.ClientSession() as http:
        for method in ("POST", "PUT", "DELETE", "PATCH"):
            async with http.request(
                method, console.base_url + "api/status", headers={"Origin": "http://evil.example"}
            ) as r:
                assert r.status == 403, method
            async with http.request(
                method, console.base_url + "api/status", headers={"Origin": f"http://127.0.0.1:{port}"}
            ) as r:
                assert r.status == 405, method  # passes the guard; no route changes state over HTTP


async def test_host_is_checked_before_the_token() -> None:
    async with ConsoleServer(sim_model="C12", port=0, token="s3cret") as srv, aiohttp.ClientSession() as http:
        port = _port(srv)
        async with http.get(
            srv.base_url + "api/status", params={"token": "s3cret"}, headers={"Host": f"evil.example:{port}"}
        ) as r:
            assert r.status == 421
        async with http.get(srv.base_url + "api/status", params={"token": "s3cret"}) as r:
            assert r.status == 200


async def test_refusals_are_logged_once_without_traceback(
    console: ConsoleServer, caplog: pytest.LogCaptureFixture
) -> None:
    port = _port(console)
    caplog.set_level(logging.INFO)
    async with aiohttp.ClientSession() as http:
        for _ in range(5):
            async with http.get(console.base_url + "api/catalog", headers={"Host": f"evil.example:{port}"}) as r:
                assert r.status == 421
    lines = [r for r in caplog.records if "refused GET /api/catalog" in r.getMessage()]
    assert len(lines) == 1 and "evil.example" in lines[0].getMessage()
    assert all(r.exc_info is None for r in caplog.records)


# -- the pieces ------------------------------------------------------------------------------


class _Transport:
    def __init__(self, sockname: tuple[str, int]) -> None:
        self.sockname = sockname

    def get_extra_info(self, name: str, default: Any = None) -> Any:
        return self.sockname if name == "sockname" else default


def _request(host: str | None, *, local: tuple[str, int] = ("127.0.0.2", 8080), origin: str | None = None) -> Any:
    headers = {} if host is None else {"Host": host}
    if origin is not None:
        headers["Origin"] = origin
    return make_mocked_request("GET", "/ws", headers=headers, transport=_Transport(local))


def test_the_address_a_connection_arrived_on_is_accepted() -> None:
    """With a wildcard bind a browser uses the machine's own address; an IP literal cannot be
    rebound, so the address the connection arrived on is one of the console's names."""
    guard = HostGuard(default_allowed_hosts("0.0.0.0"))
    assert "0.0.0.0" not in guard.allowed
    assert guard.host_problem(_request("127.0.0.2:8080")) is None
    assert guard.origin_problem(_request("127.0.0.2:8080", origin="http://127.0.0.2:8080")) is None
    assert "not one of this console's names" in (guard.host_problem(_request("127.0.0.3:8080")) or "")
    assert "another port" in (guard.host_problem(_request("127.0.0.2:8081")) or "")
    assert guard.host_problem(_request("127.0.0.2", local=("127.0.0.2", 80))) is None
    assert guard.origin_problem(_request("127.0.0.2:8080", origin="https://127.0.0.2:8080")) is None
    assert guard.origin_problem(_request("127.0.0.2:8080")) is None  # no Origin: not a browser


def test_default_names_and_the_bound_address() -> None:
    assert default_allowed_hosts("127.0.0.1") == {"localhost", "127.0.0.1", "::1"}
    assert default_allowed_hosts("::") == {"localhost", "127.0.0.1", "::1"}
    assert default_allowed_hosts("127.0.0.5", ["Bench.Example."]) == {
        "localhost",
        "127.0.0.1",
        "::1",
        "127.0.0.5",
        "bench.example",
    }
    assert "::1" in default_allowed_hosts("[0:0::1]")


@pytest.mark.parametrize(
    ("text", "parsed"),
    [
        ("localhost:8080", ("localhost", 8080)),
        ("LocalHost", ("localhost", None)),
        ("[::1]:99", ("::1", 99)),
        ("[0::1]", ("::1", None)),
        ("127.0.0.1:65535", ("127.0.0.1", 65535)),
        ("::1", None),
        ("localhost:0", None),
        ("localhost:65536", None),
        ("localhost:80x", None),
        ("a@b:1", None),
        ("a/b", None),
        ("", None),
        ("[::1", None),
        ("[::1]x", None),
    ],
)
def test_split_host_port(text: str, parsed: tuple[str, int | None] | None) -> None:
    assert split_host_port(text) == parsed


@pytest.mark.parametrize("bad", ["", "*", "*.example", "http://x", "x:80", "x/y", "a..b", "ex ample", "é.example"])
def test_bad_allow_host_names_are_refused(bad: str) -> None:
    with pytest.raises(HostNameError, match="--allow-host"):
        check_allow_host(bad)
    with pytest.raises(ValueError, match="host name"):
        ConsoleServer(sim_model="C12", allow_hosts=[bad])


def test_cli_allow_host_is_repeatable() -> None:
    args = build_parser().parse_args(
        ["console", "--sim", "C12", "--allow-host", "bench.example", "--allow-host", "10.9.8.7"]
    )
    server = build_server(args)
    assert isinstance(server, ConsoleServer)
    assert {"bench.example", "10.9.8.7", "localhost"} <= server.allowed_hosts
    banner_server = build_server(build_parser().parse_args(["console", "--sim", "C12", "--host", "0.0.0.0"]))
    assert isinstance(banner_server, ConsoleServer)
    assert "--allow-host" in banner_server.banner()


async def test_a_host_with_undecodable_bytes_is_logged_as_escaped_utf8(
    console: ConsoleServer, caplog: pytest.LogCaptureFixture
) -> None:
    # aiohttp decodes header bytes that are not UTF-8 as lone surrogates: a record holding them
    # cannot be written to a UTF-8 log file (dropped) nor sent over pytest-xdist's channel
    request = b"GET /api/status HTTP/1.1\r\nHost: rebind\xff\xfe.example\r\nConnection: close\r\n\r\n"
    with caplog.at_level(logging.WARNING, logger="topgimbal.console.guard"):
        status, _ = await _raw_get(_port(console), request)
    assert status == 421
    lines = [r.getMessage() for r in caplog.records if r.name == "topgimbal.console.guard"]
    assert any("--allow-host rebind\\udcff\\udcfe.example" in line for line in lines), lines
    for line in lines:
        line.encode("utf-8")  # raises on a lone surrogate
