"""TCP: one peer per connection, refused at the cap, dropped when its unsent bytes pass the limit."""

from __future__ import annotations

import asyncio
import socket

from ...peers import REFUSE, PeerTable, Words
from .common import TCP_PAUSE_READING_BYTES, TCP_READ_CHUNK, Forget, Limits, Sink, Throttled, fmt_addr, listen_error

WORDS = Words(
    refused="{name}: {count} clients (the limit, --max-tcp-clients): closing the new connection from {newcomer}"
)


class TcpPeer(asyncio.BufferedProtocol):
    """One TCP connection: a byte stream, replies and streams go back on it.

    Fair and bounded: each read takes at most READ_CHUNK bytes, so one flooding client cannot hold
    the event loop for more than a few frames' work before the others get their turn; a client
    whose replies back up in user space gets no further requests read until they drain (TCP's own
    back-pressure reaches it), and is dropped once they pass the limit."""

    def __init__(self, server: TcpServer) -> None:
        self.server = server
        self.transport: asyncio.Transport | None = None
        self.name = "tcp client"
        self._buf = bytearray(TCP_READ_CHUNK)

    def connection_made(self, transport: asyncio.BaseTransport) -> None:
        self.transport = transport  # type: ignore[assignment]
        self.name = f"tcp client {fmt_addr(transport.get_extra_info('peername') or ('?', 0))}"
        self.server.opened(self)

    def get_buffer(self, sizehint: int) -> bytearray:
        return self._buf

    def buffer_updated(self, nbytes: int) -> None:
        if self in self.server.peers:  # not a connection refused at the cap
            self.server.sink(self, bytes(self._buf[:nbytes]), False)

    def pause_writing(self) -> None:
        # Replies are backing up: take no more requests from this client until they drain.
        if self.transport is not None and not self.transport.is_closing():
            self.transport.pause_reading()

    def resume_writing(self) -> None:
        if self.transport is not None and not self.transport.is_closing():
            self.transport.resume_reading()

    def connection_lost(self, exc: Exception | None) -> None:
        self.server.closed(self)

    def send(self, data: bytes) -> None:
        t = self.transport
        if t is not None and not t.is_closing():
            t.write(data)
            if t.get_write_buffer_size() > self.server.limits.tcp_buffer_bytes:
                self.server.overflowed(self)

    def close(self) -> None:
        if self.transport is not None:
            self.transport.close()


class TcpServer:
    def __init__(self, sink: Sink, forget: Forget, limits: Limits | None = None) -> None:
        self.sink = sink
        self.forget = forget
        self.limits = limits or Limits()
        self.server: asyncio.AbstractServer | None = None
        self.throttled = Throttled()
        # The shared peer table: refused at the cap; a connection is forgotten when it closes.
        self.peers: PeerTable[TcpPeer, TcpPeer] = PeerTable(
            self.limits.max_tcp_clients,
            at_cap=REFUSE,
            name="tcp",
            throttle=self.throttled,
            words=WORDS,
            describe=lambda p: p.name.removeprefix("tcp client "),
            on_gone=lambda gone: self.forget(gone.value),
        )
        self.overflows = 0
        self.max_unsent = 0  # the most bytes held for one client when it was dropped
        self._name = "tcp"

    async def start(self, host: str, port: int) -> None:
        loop = asyncio.get_running_loop()
        try:
            self.server = await loop.create_server(lambda: TcpPeer(self), host, port)
        except OSError as exc:
            raise listen_error("tcp", host, port, exc) from None
        h, p = self.address
        self._name = self.peers.name = f"tcp {h}:{p}"

    @property
    def refused(self) -> int:
        """Connections closed at once because the cap was reached."""
        return self.peers.refused

    def opened(self, peer: TcpPeer) -> None:
        t = peer.transport
        assert t is not None
        if not self.peers.admit(peer, peer):
            t.abort()  # refused at the cap (counted and logged by the table)
            return
        sock = t.get_extra_info("socket")
        if sock is not None:
            try:
                sock.setsockopt(socket.SOL_SOCKET, socket.SO_SNDBUF, self.limits.tcp_sndbuf_bytes)
            except OSError:
                pass
        t.set_write_buffer_limits(high=min(TCP_PAUSE_READING_BYTES, self.limits.tcp_buffer_bytes), low=0)

    def overflowed(self, peer: TcpPeer) -> None:
        t = peer.transport
        if peer not in self.peers or t is None:
            return
        self.overflows += 1
        self.max_unsent = max(self.max_unsent, t.get_write_buffer_size())
        self.throttled.warning(
            "overflow",
            f"{self._name}: {peer.name} does not read: dropped with {t.get_write_buffer_size()} bytes unsent "
            f"(the limit is {self.limits.tcp_buffer_bytes}, --tcp-buffer-kib)",
        )
        t.abort()  # connection_lost follows: its streams and parser go with it

    def closed(self, peer: TcpPeer) -> None:
        self.peers.forget(peer)  # on_gone: the simulator drops its streams

    @property
    def address(self) -> tuple[str, int]:
        assert self.server is not None
        host, port = self.server.sockets[0].getsockname()[:2]  # type: ignore[attr-defined]
        return host, port

    async def close(self) -> None:
        for p in list(self.peers):
            p.close()
        if self.server is not None:
            self.server.close()
            await self.server.wait_closed()
