"""Issue 33.11: the camera-definition HTTP server is bounded per client, not only in total: one
client holding slow connections takes its own places, and everyone else is still served."""

from __future__ import annotations

import asyncio

import pytest

from topgimbal.camdef.http import MAX_PER_CLIENT, DefinitionServer

from .conftest import eventually

pytestmark = pytest.mark.loopback


async def _get(port: int, source: str) -> bytes:
    reader, writer = await asyncio.open_connection("127.0.0.1", port, local_addr=(source, 0))
    writer.write(b"GET /a.xml HTTP/1.0\r\n\r\n")
    await writer.drain()
    out = await asyncio.wait_for(reader.read(), 30)
    writer.close()
    return out


async def test_one_client_with_slow_connections_denies_nobody_else() -> None:
    server = DefinitionServer({"a.xml": "<x/>"})
    await server.start()
    try:
        # the attacker: 16 connections that never send their head (each held for HEAD_TIMEOUT_S)
        slow = [await asyncio.open_connection("127.0.0.1", server.port, local_addr=("127.0.0.1", 0)) for _ in range(16)]
        await eventually(
            lambda: server.refused == 16 - MAX_PER_CLIENT, 5, "the connections beyond the client's share refused"
        )
        assert server.active == MAX_PER_CLIENT and server.refused == 16 - MAX_PER_CLIENT
        replies = [await _get(server.port, f"127.0.0.{2 + i % 10}") for i in range(40)]  # 40 normal GETs
        assert all(r.startswith(b"HTTP/1.1 200") and r.endswith(b"<x/>") for r in replies), [r[:40] for r in replies]
        for _, w in slow:
            w.close()
    finally:
        await server.close()
