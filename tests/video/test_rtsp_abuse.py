"""The RTSP server under hostile and careless clients: answers as RFC 2326 says, refuses what it
cannot serve at SETUP (not later, on the loop, for every picture), bounds sessions from SETUP on,
closes connections nothing is heard from, and one broken receiver never starves the others.

The server runs in-process with a stream fed by hand (no encoder): fast and deterministic."""

from __future__ import annotations

import asyncio
import contextlib
import logging
import socket
import time
from collections.abc import AsyncIterator
from typing import Any

import pytest

from topgimbal.video import rtsp, rtsp_connection
from topgimbal.video.encode import AccessUnit
from topgimbal.video.rtsp import RtspServer, Stream, Transport, parse_transport
from waiting import until

pytestmark = pytest.mark.loopback

SPS = b"\x67\x42\xc0\x1f\xda\x01\x40\x16\xe8"
PPS = b"\x68\xce\x3c\x80"


def _picture(n: int) -> AccessUnit:
    """A keyframe whose slice carries `n` (0..127, no start code inside) so a receiver can tell
    pictures apart."""
    start = b"\x00\x00\x00\x01"
    return AccessUnit(start + SPS + start + PPS + start + b"\x65" + bytes([0x80 + n]) * 32, True, n / 30, "h264")


@pytest.fixture
async def server() -> AsyncIterator[RtspServer]:
    stream = Stream("/stream=1", "h264")
    stream.publish(_picture(0))  # parameter sets known: DESCRIBE answers at once
    srv = await RtspServer("127.0.0.1", 0, [stream]).start()
    try:
        yield srv
    finally:
        await srv.close()


class Client:
    """A raw RTSP client: sends what it is told, reads answers and interleaved frames."""

    def __init__(self, reader: asyncio.StreamReader, writer: asyncio.StreamWriter, url: str) -> None:
        self.reader, self.writer, self.url = reader, writer, url
        self.cseq = 0
        self.frames: list[tuple[int, bytes]] = []

    @classmethod
    async def connect(cls, srv: RtspServer) -> Client:
        r, w = await asyncio.open_connection("127.0.0.1", srv.port)
        return cls(r, w, srv.url("/stream=1"))

    async def raw(self, text: str) -> tuple[int, dict[str, str]]:
        self.writer.write(text.encode())
        return await self.answer()

    async def answer(self) -> tuple[int, dict[str, str]]:
        while True:
            first = await asyncio.wait_for(self.reader.readexactly(1), 10)
            if first == b"$":  # an interleaved frame ahead of the answer
                await self.frame(first)
                continue
            head = first + await asyncio.wait_for(self.reader.readuntil(b"\r\n\r\n"), 10)
            lines = head.decode().split("\r\n")
            headers = {k.strip().lower(): v.strip() for k, _, v in (x.partition(":") for x in lines[1:] if x)}
            body = int(headers.get("content-length", "0"))
            if body:
                await self.reader.readexactly(body)
            return int(lines[0].split()[1]), headers

    async def frame(self, first: bytes = b"") -> tuple[int, bytes]:
        head = first + await asyncio.wait_for(self.reader.readexactly(4 - len(first)), 10)
        assert head[:1] == b"$", head
        data = await asyncio.wait_for(self.reader.readexactly(int.from_bytes(head[2:4], "big")), 10)
        self.frames.append((head[1], data))
        return head[1], data

    async def ask(self, method: str, url: str | None = None, **headers: str) -> tuple[int, dict[str, str]]:
        self.cseq += 1
        lines = [f"{method} {url or self.url} RTSP/1.0", f"CSeq: {self.cseq}"]
        lines += [f"{k.replace('_', '-')}: {v}" for k, v in headers.items()]
        return await self.raw("\r\n".join(lines) + "\r\n\r\n")

    async def play_tcp(self, channels: str = "0-1") -> str:
        code, h = await self.ask("SETUP", Transport=f"RTP/AVP/TCP;unicast;interleaved={channels}")
        assert code == 200, code
        sid = h["session"].split(";")[0]
        code, _ = await self.ask("PLAY", Session=sid)
        assert code == 200, code
        return sid

    async def closed(self) -> bool:
        """True once the server has closed this connection (reads what is still on the way)."""
        with contextlib.suppress(asyncio.TimeoutError, ConnectionError):
            while await asyncio.wait_for(self.reader.read(65536), 10):
                pass
            return True
        return False

    def close(self) -> None:
        self.writer.close()


@pytest.mark.parametrize(
    ("request_text", "status"),
    [
        ("OPTIONS {url} RTSP/1.0\r\n\r\n", 400),  # no CSeq (RFC 2326 12.17: every request has one)
        ("OPTIONS {url} RTSP/1.0\r\nCSeq: one\r\n\r\n", 400),
        ("FROBNICATE {url} RTSP/1.0\r\nCSeq: 1\r\n\r\n", 501),  # a method nobody knows
        ("PAUSE {url} RTSP/1.0\r\nCSeq: 1\r\n\r\n", 405),  # known, not offered
        ("OPTIONS {url} RTSP/2.0\r\nCSeq: 1\r\n\r\n", 505),
        ("TEARDOWN {url} RTSP/1.0\r\nCSeq: 1\r\nSession: 0BADC0FFEE\r\n\r\n", 454),
        ("TEARDOWN {url} RTSP/1.0\r\nCSeq: 1\r\n\r\n", 454),  # no session at all
        ("GET_PARAMETER {url} RTSP/1.0\r\nCSeq: 1\r\nSession: 0BADC0FFEE\r\n\r\n", 454),
        ("GET_PARAMETER {url} RTSP/1.0\r\nCSeq: 1\r\n\r\n", 200),  # a keep-alive naming no session
        ("PLAY {url} RTSP/1.0\r\nCSeq: 1\r\n\r\n", 454),  # PLAY without SETUP
        ("SETUP {url} RTSP/1.0\r\nCSeq: 1\r\nSession: 0BADC0FFEE\r\nTransport: RTP/AVP/TCP\r\n\r\n", 454),
        ("SETUP {url} RTSP/1.0\r\nCSeq: 1\r\nTransport: RTP/AVP/TCP;unicast;interleaved=300-301\r\n\r\n", 461),
        ("SETUP {url} RTSP/1.0\r\nCSeq: 1\r\nTransport: RTP/AVP/TCP;unicast;interleaved=-1\r\n\r\n", 461),
        ("SETUP {url} RTSP/1.0\r\nCSeq: 1\r\nTransport: RTP/AVP;unicast;client_port=99999-100000\r\n\r\n", 461),
        ("SETUP {url} RTSP/1.0\r\nCSeq: 1\r\nTransport: RTP/AVP;unicast;client_port=0-1\r\n\r\n", 461),
        ("SETUP {url} RTSP/1.0\r\nCSeq: 1\r\nTransport: RTP/SAVP;unicast;client_port=5000-5001\r\n\r\n", 461),
        ("SETUP {url} RTSP/1.0\r\nCSeq: 1\r\nTransport: RTP/AVP;multicast;client_port=5000-5001\r\n\r\n", 461),
        ("SETUP {url} RTSP/1.0\r\nCSeq: 1\r\n\r\n", 461),
        ("SETUP rtsp://127.0.0.1:1/nope RTSP/1.0\r\nCSeq: 1\r\nTransport: RTP/AVP/TCP\r\n\r\n", 404),
    ],
)
async def test_bad_requests_get_the_rfc_answer_and_the_connection_goes_on(
    server: RtspServer, request_text: str, status: int
) -> None:
    c = await Client.connect(server)
    try:
        code, headers = await c.raw(request_text.format(url=c.url))
        assert code == status
        if status == 405:
            assert headers["allow"] == ", ".join(rtsp.SUPPORTED)  # SET_PARAMETER too, as OPTIONS says
        if "CSeq: 1" in request_text:
            assert headers["cseq"] == "1"
        else:
            assert "cseq" not in headers  # no made-up CSeq for a request that had none
        assert (await c.ask("OPTIONS"))[0] == 200  # the same connection still serves
        assert not server.streams["/stream=1"].sessions  # nothing half set up
    finally:
        c.close()


def test_transport_header_is_read_as_rfc_2326_says() -> None:
    assert parse_transport("RTP/AVP/TCP;unicast;interleaved=4-5") == Transport(True, 4, 5)
    assert parse_transport("RTP/AVP/TCP;unicast", {0, 1, 2, 3}) == Transport(True, 4, 5)  # lowest free pair
    assert parse_transport("RTP/AVP;unicast;client_port=5000-5001") == Transport(False, 5000, 5001)
    assert parse_transport("RTP/AVP/UDP;unicast;client_port=5000") == Transport(False, 5000, 5001)
    # The client's alternatives in its order of preference: the first one this server can serve.
    assert parse_transport("RTP/SAVP;unicast;client_port=6000-6001,RTP/AVP/TCP;interleaved=2-3") == Transport(
        True, 2, 3
    )
    for bad in (
        "RTP/AVP/TCP;interleaved=255-256",
        "RTP/AVP/TCP;interleaved=x-y",
        "RTP/AVP/TCP;interleaved=٣-٤",  # Unicode digits are not RTSP's
        "RTP/AVP;client_port=65535",  # no room for the RTCP port
        "RTP/AVP;client_port=+5000-5001",
        "RTP/AVP;client_port=" + "9" * 5000,
        "RTP/AVP",
        "",
        ",,,;;;",
    ):
        assert parse_transport(bad) is None, bad
    assert parse_transport("RTP/AVP/TCP", set(range(256))) is None  # every channel taken


async def test_a_client_asking_for_odd_channels_or_ports_cannot_starve_the_others(server: RtspServer) -> None:
    stream = server.streams["/stream=1"]
    good = await Client.connect(server)
    bad = await Client.connect(server)
    try:
        await good.play_tcp()
        # Before: both SETUPs were accepted, and every picture raised on the event loop
        # (struct.error / OverflowError), so receivers after the bad one got nothing.
        for transport in ("RTP/AVP/TCP;unicast;interleaved=300-301", "RTP/AVP;unicast;client_port=99999-100000"):
            code, _ = await bad.ask("SETUP", Transport=transport)
            assert code == 461
            assert (await bad.ask("PLAY"))[0] == 454
        for n in range(1, 6):
            stream.publish(_picture(n))
        got: set[int] = set()
        while len(got) < 5:
            _, data = await good.frame()
            if data[12] & 0x1F == 5:  # the slice (the parameter sets go first)
                got.add(data[13] - 0x80)
        assert got == {1, 2, 3, 4, 5}
    finally:
        good.close()
        bad.close()


async def test_a_receiver_that_fails_is_dropped_and_the_others_get_the_picture(
    server: RtspServer, monkeypatch: Any, caplog: Any
) -> None:
    stream = server.streams["/stream=1"]
    clients = [await Client.connect(server) for _ in range(3)]
    try:
        for c in clients:
            await c.play_tcp()
        broken = next(iter(stream.receivers))

        def fail(au: AccessUnit, rtp_time: int) -> None:
            raise RuntimeError("a transport in a state nobody foresaw")

        monkeypatch.setattr(broken, "send_picture", fail)
        with caplog.at_level(logging.ERROR, "topgimbal.video.rtsp"):
            stream.publish(_picture(1))  # before: the exception left publish, the rest got nothing
        assert broken not in stream.receivers and broken not in stream.sessions
        assert len(stream.receivers) == 2
        assert "dropping that receiver" in caplog.text
    finally:
        for c in clients:
            c.close()


async def test_sessions_count_from_setup_so_one_client_cannot_hold_more(
    server: RtspServer, monkeypatch: Any, caplog: Any
) -> None:
    monkeypatch.setattr(rtsp_connection, "MAX_RECEIVERS", 3)
    stream = server.streams["/stream=1"]
    c = await Client.connect(server)
    other = await Client.connect(server)
    try:
        sids = []
        for i in range(3):  # UDP sessions: each holds two sockets from SETUP on
            code, h = await c.ask("SETUP", Transport=f"RTP/AVP;unicast;client_port={40000 + 2 * i}-{40001 + 2 * i}")
            assert code == 200
            sids.append(h["session"].split(";")[0])
        with caplog.at_level(logging.WARNING, "topgimbal.video.rtsp"):
            # Before: sessions counted only once playing: any number could be set up, then played.
            assert (await c.ask("SETUP", Transport="RTP/AVP/TCP;unicast;interleaved=0-1"))[0] == 453
            assert (await other.ask("SETUP", Transport="RTP/AVP/TCP;unicast;interleaved=0-1"))[0] == 453
        assert "3 sessions already (limit)" in caplog.text
        for sid in sids:
            assert (await c.ask("PLAY", Session=sid))[0] == 200
        assert len(stream.receivers) == len(stream.sessions) == 3
        assert (await c.ask("TEARDOWN", Session=sids[0]))[0] == 200
        assert len(stream.sessions) == 2
        await other.play_tcp()  # a place came free
        c.close()
        assert await c.closed()
        # the server sees the close on its next turn
        await until("the closed session gone", lambda: len(stream.sessions), lambda n: n == 1, bound_s=30)
        assert len(stream.sessions) == 1 and all(s.conn is not None for s in stream.sessions)
    finally:
        c.close()
        other.close()


async def test_connections_nothing_is_heard_from_are_closed(server: RtspServer, monkeypatch: Any, caplog: Any) -> None:
    monkeypatch.setattr(rtsp, "MAX_CONNECTIONS", 3)
    idle = [await Client.connect(server) for _ in range(3)]
    late = await Client.connect(server)
    try:
        assert await late.closed()  # before: three idle connections kept every client out for good
        assert server.reap() == 0  # just opened: nothing is closed
        # A clock past the idle limit (the reaper runs every few seconds with the real one).
        with caplog.at_level(logging.WARNING, "topgimbal.video.rtsp"):
            assert server.reap(time.monotonic() + rtsp.IDLE_CLOSE_S + 1) == 3
        assert "nothing heard for" in caplog.text
        for c in idle:
            assert await c.closed()
        fresh = await Client.connect(server)
        try:
            assert (await fresh.ask("OPTIONS"))[0] == 200
        finally:
            fresh.close()
    finally:
        for c in (*idle, late):
            c.close()


async def test_a_playing_client_that_keeps_talking_is_not_closed(server: RtspServer) -> None:
    c = await Client.connect(server)
    try:
        sid = await c.play_tcp()
        conn = next(iter(server.connections))
        played = server.connections.heard_at(conn)
        assert played is not None
        await asyncio.sleep(0.01)  # the clock moves past the PLAY
        before = time.monotonic()
        assert before > played
        assert (await c.ask("GET_PARAMETER", Session=sid))[0] == 200  # a keep-alive ...
        # ... renews the connection: a reaper that comes IDLE_CLOSE_S after it started leaves it
        # (heard at PLAY only, it would be closed: `before` is later than that).
        assert server.reap(before + rtsp.IDLE_CLOSE_S) == 0
        await asyncio.sleep(0.01)
        before = time.monotonic()
        c.writer.write(b"$\x01\x00\x04abcd")  # interleaved RTCP counts as well
        await c.writer.drain()
        for _ in range(1000):
            heard = server.connections.heard_at(conn)
            if heard is not None and heard >= before:
                break
            await asyncio.sleep(0.01)
        assert server.reap(before + rtsp.IDLE_CLOSE_S) == 0
        assert (await c.ask("OPTIONS"))[0] == 200
    finally:
        c.close()


async def test_a_setup_that_cannot_get_udp_sockets_fails_alone(server: RtspServer, monkeypatch: Any) -> None:
    loop = asyncio.get_running_loop()

    async def no_sockets(*args: Any, **kwargs: Any) -> Any:
        raise OSError(24, "Too many open files")

    c = await Client.connect(server)
    try:
        with monkeypatch.context() as m:
            m.setattr(loop, "create_datagram_endpoint", no_sockets)
            code, _ = await c.ask("SETUP", Transport="RTP/AVP;unicast;client_port=40000-40001")
        assert code == 503  # before: 500 after a logged traceback
        assert not server.streams["/stream=1"].sessions  # no place held by the failed SETUP
        await c.play_tcp()
    finally:
        c.close()


async def test_a_client_that_reads_no_answers_cannot_grow_the_servers_memory(
    server: RtspServer, monkeypatch: Any, caplog: Any
) -> None:
    monkeypatch.setattr(rtsp_connection, "MAX_BUFFERED_BYTES", 200_000)
    stream = server.streams["/stream=1"]
    stream.params["sps"] = SPS + bytes(6000)  # big answers (DESCRIBE's SDP carries it): quick to show
    loop = asyncio.get_running_loop()
    client = socket.socket()
    # Each request in its own segment: with Nagle's algorithm the requests held back behind an
    # unacknowledged one arrive together, and the pipelining limit would close the connection
    # whatever the answers do.
    client.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)
    client.setblocking(False)
    await loop.sock_connect(client, ("127.0.0.1", server.port))
    for _ in range(200):
        if server.connections:
            break
        await asyncio.sleep(0.01)
    conn = next(iter(server.connections))
    assert conn.transport is not None
    request = f"DESCRIBE {server.url('/stream=1')} RTSP/1.0\r\nCSeq: 1\r\n\r\n".encode()
    most = 0
    try:
        with caplog.at_level(logging.WARNING, "topgimbal.video.rtsp"):
            for _ in range(4000):  # up to 32 MB of answers, which the client never reads
                if conn.transport.is_closing():
                    break
                with contextlib.suppress(BlockingIOError):
                    client.send(request)
                # One request at a time, at a rate the server keeps up with (a burst of them
                # has its own limit, MAX_PIPELINED).
                await asyncio.sleep(0.001)
                most = max(most, conn.transport.get_write_buffer_size())
        # Before: the answers piled up in memory without bound.
        assert conn.transport.is_closing(), f"still answering into memory ({most} bytes unsent)"
        assert most < rtsp_connection.MAX_BUFFERED_BYTES + rtsp_connection.MAX_PIPELINED * 10_000
        assert "requests waiting (answers unread" in caplog.text
    finally:
        client.close()
