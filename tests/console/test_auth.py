"""The access rule: loopback by default; a token for anything else; every request carries it."""

from __future__ import annotations

import aiohttp
import pytest

from topgimbal.cli.console_cmd import build_server
from topgimbal.cli.main import build_parser
from topgimbal.console import ConsoleServer, is_loopback, needs_token, resolve_token
from topgimbal.console.auth import TOKEN_COOKIE, TOKEN_HEADER

pytestmark = pytest.mark.loopback


@pytest.mark.parametrize("host", ["127.0.0.1", "127.0.0.2", "localhost", "::1", "[::1]"])
def test_loopback_hosts_need_no_token(host: str) -> None:
    assert is_loopback(host)
    assert not needs_token(host)
    assert resolve_token(host, None) == (None, False)


@pytest.mark.parametrize("host", ["0.0.0.0", "::", "192.0.2.7", "198.51.100.7", "camera-bench.example"])
def test_other_hosts_need_a_token(host: str) -> None:
    assert not is_loopback(host)
    assert needs_token(host)
    token, generated = resolve_token(host, None)
    assert generated and token and len(token) >= 16
    assert resolve_token(host, "given") == ("given", False)


def test_generated_tokens_differ() -> None:
    assert resolve_token("0.0.0.0", None)[0] != resolve_token("0.0.0.0", None)[0]


def test_default_host_is_loopback() -> None:
    args = build_parser().parse_args(["console", "--sim", "C12"])
    assert args.host == "127.0.0.1"
    server = build_server(args)
    assert isinstance(server, ConsoleServer)
    assert server.host == "127.0.0.1"
    assert server.token is None
    assert server.page_url == "http://127.0.0.1:8080/"
    assert ConsoleServer(sim_model="C12").host == "127.0.0.1"


def test_cli_non_loopback_host_gets_a_token_in_the_url() -> None:
    # Decided without starting anything: never binds the address.
    server = build_server(build_parser().parse_args(["console", "--sim", "C12", "--host", "0.0.0.0", "--port", "9999"]))
    assert isinstance(server, ConsoleServer)
    assert server.token and server.token_generated
    # A URL a browser opens (http://0.0.0.0:... is none; issue 35.6), and where it comes from elsewhere.
    assert server.page_url == f"http://127.0.0.1:9999/?token={server.token}"
    assert "from another machine" in server.banner()
    assert "generated" in server.banner()


def test_cli_explicit_token_is_used() -> None:
    server = build_server(build_parser().parse_args(["console", "--sim", "C12", "--host", "0.0.0.0", "--token", "abc"]))
    assert isinstance(server, ConsoleServer)
    assert (server.token, server.token_generated) == ("abc", False)


def test_cli_url_and_model_after_the_subcommand() -> None:
    args = build_parser().parse_args(["console", "--url", "udp://127.0.0.1:9", "--model", "sip"])
    server = build_server(args)
    assert isinstance(server, ConsoleServer)
    assert (server.url, server.model, server.sim_model) == ("udp://127.0.0.1:9", "SIP", None)
    args = build_parser().parse_args(["--url", "udp://127.0.0.1:9", "--model", "C12", "console"])
    server = build_server(args)
    assert isinstance(server, ConsoleServer)
    assert (server.url, server.model) == ("udp://127.0.0.1:9", "C12")


def test_cli_rejects_missing_camera() -> None:
    with pytest.raises(ValueError, match="--sim"):
        build_server(build_parser().parse_args(["console"]))
    with pytest.raises(ValueError, match="--model"):
        build_server(build_parser().parse_args(["console", "--url", "udp://127.0.0.1:9"]))


async def test_token_enforced_on_every_route() -> None:
    async with ConsoleServer(sim_model="C12", host="127.0.0.1", port=0, token="s3cret") as srv:
        base = srv.base_url
        async with aiohttp.ClientSession() as http:
            for path in ("", "api/catalog", "api/status", "static/app.js", "static/style.css", "ws"):
                async with http.get(base + path) as r:
                    assert r.status == 401, path
                    assert "token" in (await r.json())["message"]
                async with http.get(base + path, params={"token": "wrong"}) as r:
                    assert r.status == 401, path
            async with http.get(base, params={"token": "s3cret"}) as r:
                assert r.status == 200
                assert 'data-testid="yaw"' in await r.text()
                assert r.cookies[TOKEN_COOKIE].value == "s3cret"
            async with http.get(base + "api/catalog", headers={TOKEN_HEADER: "s3cret"}) as r:
                assert r.status == 200
                assert (await r.json())["model"]["name"] == "C12"
            async with http.get(base + "static/app.js", headers={"Authorization": "Bearer s3cret"}) as r:
                assert r.status == 200
        # the cookie set by opening the page lets the page's own module imports through
        async with aiohttp.ClientSession(cookie_jar=aiohttp.CookieJar(unsafe=True)) as http:
            async with http.get(base, params={"token": "s3cret"}) as r:
                assert r.status == 200
            async with http.get(base + "static/lib/conn.js") as r:
                assert r.status == 200
        async with aiohttp.ClientSession() as http:
            with pytest.raises(aiohttp.WSServerHandshakeError) as exc:
                async with http.ws_connect(base + "ws"):
                    pass
            assert exc.value.status == 401
            async with http.ws_connect(base + "ws?token=s3cret") as ws:
                hello = await ws.receive_json(timeout=30)
                assert hello["type"] == "hello"
                assert hello["model"]["name"] == "C12"


async def test_loopback_without_token_is_open_but_refuses_cross_site_sockets() -> None:
    async with ConsoleServer(sim_model="C12", port=0) as srv:
        assert srv.token is None
        async with aiohttp.ClientSession() as http:
            async with http.get(srv.base_url + "api/catalog") as r:
                assert r.status == 200
            with pytest.raises(aiohttp.WSServerHandshakeError) as exc:
                async with http.ws_connect(srv.base_url + "ws", headers={"Origin": "http://evil.example"}):
                    pass
            assert exc.value.status == 403
            host = srv.base_url.split("//")[1].rstrip("/")
            async with http.ws_connect(srv.base_url + "ws", headers={"Origin": f"http://{host}"}) as ws:
                assert (await ws.receive_json(timeout=30))["type"] == "hello"
