"""Issue 43.9: the media and definition servers bound slow clients per address, and what a client
behind the same address as an attacker (the same NAT, the same host) gets: refused while the
attacker holds that address's places, served as soon as they are given back (the attacker's
connections close or reach the server's socket timeout). Other addresses are never refused."""

from __future__ import annotations

import asyncio
import socket
from pathlib import Path

import pytest

from topgimbal.camdef import http as camdef_http
from topgimbal.camdef.http import DefinitionServer
from topgimbal.video import media_http
from topgimbal.video.media_http import MediaServer

pytestmark = pytest.mark.loopback


def media_get(port: int, source: str) -> bytes:
    with socket.create_connection(("127.0.0.1", port), timeout=30, source_address=(source, 0)) as s:
        s.sendall(b"GET /IMG_0001.jpg HTTP/1.0\r\n\r\n")
        out = b""
        while chunk := s.recv(65536):
            out += chunk
        return out


def test_media_a_neighbour_of_the_attacker_waits_for_the_socket_timeout(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.setattr(media_http, "SOCKET_TIMEOUT_S", 2.0)
    card = tmp_path / "card"
    card.mkdir()
    (card / "IMG_0001.jpg").write_bytes(b"jpeg")
    server = MediaServer(card).start()
    port = int(server.httpd.server_address[1])
    try:
        # the attacker, on 127.0.0.5: its address's places held by connections that never send a head
        held = [socket.create_connection(("127.0.0.1", port), source_address=("127.0.0.5", 0))
                for _ in range(media_http.MAX_PER_CLIENT)]  # fmt: skip
        neighbour = media_get(port, "127.0.0.5")  # same address: refused at once
        assert neighbour.startswith(b"HTTP/1.0 503"), neighbour
        assert media_get(port, "127.0.0.6").endswith(b"jpeg")  # another address: served
        for s in held:  # the server closes them at its socket timeout: the places come back
            s.settimeout(30)
            assert s.recv(10) == b""
        assert media_get(port, "127.0.0.5").endswith(b"jpeg")
    finally:
        server.stop()


async def test_definitions_a_neighbour_of_the_attacker_waits_for_the_head_timeout(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    monkeypatch.setattr(camdef_http, "HEAD_TIMEOUT_S", 1.0)
    server = DefinitionServer({"a.xml": "<x/>"})
    await server.start()

    async def get(source: str) -> bytes:
        reader, writer = await asyncio.open_connection("127.0.0.1", server.port, local_addr=(source, 0))
        writer.write(b"GET /a.xml HTTP/1.0\r\n\r\n")
        await writer.drain()
        try:
            out = await asyncio.wait_for(reader.read(), 30)
        except ConnectionResetError:  # closed unanswered, before or while the request went
            out = b""
        writer.close()
        return out

    try:
        held = [await asyncio.open_connection("127.0.0.1", server.port, local_addr=("127.0.0.7", 0))
                for _ in range(camdef_http.MAX_PER_CLIENT)]  # fmt: skip
        await asyncio.sleep(0.2)
        assert await get("127.0.0.7") == b""  # same address: closed unanswered
        assert (await get("127.0.0.8")).endswith(b"<x/>")  # another address: served
        for reader, _w in held:  # answered 400 and closed by the server at its head timeout
            assert (await asyncio.wait_for(reader.read(), 30)).startswith(b"HTTP/1.1 400")
        assert (await get("127.0.0.7")).endswith(b"<x/>")
        for _r, w in held:
            w.close()
    finally:
        await server.close()
