"""The console's MJPEG viewers under careless browsers: a viewer that stops reading is dropped
(it held one of the MAX_VIEWERS places for good), one that leaves mid-picture ends quietly, the
places beyond MAX_VIEWERS are refused with 503, and the viewers that read keep getting pictures.

The routes run on a real aiohttp server on loopback; the relay is fed by hand (no camera)."""

from __future__ import annotations

import asyncio
import contextlib
import logging
import socket
from collections.abc import AsyncIterator
from types import SimpleNamespace
from typing import Any

import pytest
from aiohttp import web

from topgimbal.video import relay as relay_mod
from topgimbal.video import webconsole
from topgimbal.video.relay import Relay
from topgimbal.video.webconsole import ConsoleVideo
from waiting import until

pytestmark = pytest.mark.loopback

PICTURE = b"\xff\xd8" + bytes(200_000) + b"\xff\xd9"  # big enough to fill socket buffers fast


class HandFedRelay(Relay):
    """A relay whose pictures come from the test, not from a reader thread."""

    def _ensure_reader(self) -> None:
        pass


@pytest.fixture
async def console() -> AsyncIterator[tuple[ConsoleVideo, int]]:
    video = ConsoleVideo(SimpleNamespace(model="C12", url=None, sim=None, cam=None))
    video.relays = {"visible": HandFedRelay("visible", "rtsp://127.0.0.1:1/none")}
    app = web.Application()
    video.add_routes(app)
    runner = web.AppRunner(app)
    await runner.setup()
    site = web.TCPSite(runner, "127.0.0.1", 0)
    await site.start()
    port = site._server.sockets[0].getsockname()[1]  # type: ignore[union-attr]
    try:
        yield video, port
    finally:
        await video.close()
        await runner.cleanup()


def _viewer(port: int, *, reads: bool) -> socket.socket:
    s = socket.socket()
    if not reads:  # a small window: the server's writes block soon
        s.setsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF, 4096)
    s.connect(("127.0.0.1", port))
    s.setblocking(False)
    # As the console's own page asks (it may use every place, OPERATOR_RESERVED included).
    s.sendall(b"GET /video/visible.mjpg HTTP/1.1\r\nHost: 127.0.0.1\r\nSec-Fetch-Site: same-origin\r\n\r\n")
    return s


async def _read_some(s: socket.socket) -> bytes:
    return await asyncio.wait_for(asyncio.get_running_loop().sock_recv(s, 1 << 20), 10)


async def test_a_viewer_that_stops_reading_gives_its_place_back(
    console: tuple[ConsoleVideo, int], monkeypatch: Any, caplog: Any
) -> None:
    video, port = console
    relay = video.relays["visible"]
    monkeypatch.setattr(relay_mod, "MAX_VIEWERS", 2)
    monkeypatch.setattr(webconsole, "VIEWER_STALL_S", 0.5)
    reader = _viewer(port, reads=True)
    stalled = _viewer(port, reads=False)
    extra: socket.socket | None = None
    try:
        await until("both viewers' requests arrived", lambda: relay.viewers, lambda n: n == 2, bound_s=30)
        assert relay.viewers == 2
        extra = _viewer(port, reads=True)
        answer = await _read_some(extra)
        assert answer.startswith(b"HTTP/1.1 503") and b"2 viewers already watch" in answer
        extra.close()
        # Pictures keep coming; the stalled viewer's writes block until it is dropped (before:
        # it kept its place for good and every later viewer got 503). The reader gets them all.
        received = 0
        with caplog.at_level(logging.WARNING, "topgimbal.video.console"):
            for _ in range(400):
                await relay._publish(PICTURE)
                await asyncio.sleep(0.02)
                received += len(await _read_some(reader))
                if relay.viewers == 1:
                    break
        assert relay.viewers == 1, "the viewer that stopped reading still holds its place"
        assert "took no picture for" in caplog.text
        assert received > len(PICTURE)
        extra = _viewer(port, reads=True)  # the place is free again
        assert (await _read_some(extra)).startswith(b"HTTP/1.1 200")
    finally:
        for s in (reader, stalled, extra):
            if s is not None:
                s.close()


async def test_a_viewer_that_leaves_mid_picture_ends_quietly(console: tuple[ConsoleVideo, int], caplog: Any) -> None:
    video, port = console
    relay = video.relays["visible"]
    gone = _viewer(port, reads=False)
    for _ in range(200):
        if relay.viewers == 1:
            break
        await asyncio.sleep(0.02)
    with caplog.at_level(logging.ERROR):
        for _ in range(60):  # ~12 MB: past the kernel's buffers, the handler waits in its write
            await relay._publish(PICTURE)
            await asyncio.sleep(0.01)
        gone.setsockopt(socket.SOL_SOCKET, socket.SO_LINGER, b"\x01\x00\x00\x00\x00\x00\x00\x00")
        gone.close()  # a reset, as a closed tab's
        for _ in range(200):
            await relay._publish(PICTURE)
            await asyncio.sleep(0.02)
            if relay.viewers == 0:
                break
    assert relay.viewers == 0
    # Before: aiohttp's "Connection lost" (a ConnectionError, not a ConnectionResetError) escaped
    # the handler and was logged as "Error handling request" with a traceback.
    assert "Error handling request" not in caplog.text and "Traceback" not in caplog.text


@pytest.mark.parametrize("lens", [["visible"], {"a": 1}, 3, None, "ir"])
@pytest.mark.parametrize("route", ["point", "track"])
async def test_a_bad_lens_is_a_clear_400(console: tuple[ConsoleVideo, int], route: str, lens: Any) -> None:
    import aiohttp

    _, port = console
    body = {"lens": lens, "x": 0.5, "y": 0.5, "x0": 0.1, "y0": 0.1, "x1": 0.2, "y1": 0.2}
    async with (
        aiohttp.ClientSession() as http,
        http.post(f"http://127.0.0.1:{port}/api/video/{route}", json=body) as resp,
    ):
        # Before: a list or an object as the lens raised TypeError (unhashable): a 500.
        assert resp.status == 400
        assert "lens must be one of visible, thermal" in (await resp.json())["message"]


async def test_other_clients_leave_the_operators_places_free(console: tuple[ConsoleVideo, int]) -> None:
    """Clients that are not the console's page (scripts, direct URLs) take at most
    MAX_VIEWERS - OPERATOR_RESERVED places; the console's own page still gets a picture.
    Before: any 8 viewers locked the operator's page out with 503."""
    video, port = console
    relay = video.relays["visible"]
    others: list[socket.socket] = []
    mine: list[socket.socket] = []
    try:
        for _ in range(relay_mod.MAX_VIEWERS):
            s = socket.create_connection(("127.0.0.1", port))
            s.setblocking(False)
            s.sendall(b"GET /video/visible.mjpg HTTP/1.1\r\nHost: 127.0.0.1\r\nSec-Fetch-Site: none\r\n\r\n")
            others.append(s)
        await eventually_viewers(relay, relay_mod.MAX_VIEWERS - relay_mod.OPERATOR_RESERVED)
        refused = 0
        for s in others:
            with contextlib.suppress(asyncio.TimeoutError):
                answer = await asyncio.wait_for(asyncio.get_running_loop().sock_recv(s, 4096), 1.0)
                refused += answer.startswith(b"HTTP/1.1 503") and b"kept for the console's page" in answer
        assert refused == relay_mod.OPERATOR_RESERVED
        for _ in range(relay_mod.OPERATOR_RESERVED):
            mine.append(_viewer(port, reads=True))
        await eventually_viewers(relay, relay_mod.MAX_VIEWERS)
        await relay._publish(PICTURE)
        for s in mine:
            assert (await _read_some(s)).startswith(b"HTTP/1.1 200")
        extra = _viewer(port, reads=True)  # every place taken now, the operator's too
        mine.append(extra)
        assert (await _read_some(extra)).startswith(b"HTTP/1.1 503")
    finally:
        for s in others + mine:
            s.close()


async def eventually_viewers(relay: Any, n: int) -> None:
    await until(f"{n} viewers", lambda: relay.viewers, lambda v: v == n, bound_s=10)  # tests/waiting.py
