"""The console's answer to requests made by other sites' pages (issue 27), route by route:
`Sec-Fetch-Site` other than same-origin / none, or (for browsers that send none) a foreign Origin
or Referer, is 403 on every GET route, media included; scripts that send none of these pass.
The browser's view of it is tests/video/test_console_embedding.py."""

from __future__ import annotations

import aiohttp
import pytest

from topgimbal.console import ConsoleServer

pytestmark = pytest.mark.loopback


@pytest.mark.parametrize(
    ("headers", "status"),
    [
        ({"Sec-Fetch-Site": "cross-site", "Sec-Fetch-Dest": "image"}, 403),
        ({"Sec-Fetch-Site": "same-site", "Sec-Fetch-Dest": "iframe"}, 403),
        ({"Sec-Fetch-Site": "garbage"}, 403),
        ({"Referer": "http://127.0.0.1:1/evil.html"}, 403),  # a browser without Sec-Fetch-*
        ({"Referer": "https://evil.example/"}, 403),
        ({"Referer": "not a url"}, 403),
        ({"Origin": "http://evil.example"}, 403),
        ({"Sec-Fetch-Site": "same-origin"}, 200),
        ({"Sec-Fetch-Site": "none"}, 200),
        ({}, 200),  # scripts, curl
    ],
)
async def test_every_get_route_checks_where_the_request_comes_from(headers: dict[str, str], status: int) -> None:
    async with ConsoleServer(sim_model="C12", port=0) as srv, aiohttp.ClientSession() as http_session:
        for path in ("", "static/app.js", "api/status", "api/catalog", "api/video", "api/traffic.pcap",
                     "video/visible.mjpg"):  # fmt: skip
            async with http_session.get(srv.base_url + path, headers=headers) as r:
                assert r.status == status, (path, headers)
                if status == 403:
                    body = await r.json()
                    assert body["error"] == "forbidden", body


async def test_an_own_referer_passes() -> None:
    async with ConsoleServer(sim_model="C12", port=0) as srv, aiohttp.ClientSession() as http_session:
        r = await http_session.get(srv.base_url + "api/status", headers={"Referer": srv.base_url})
        assert r.status == 200
        r.release()
