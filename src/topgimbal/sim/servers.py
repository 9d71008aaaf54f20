"""Thin asyncio transports around the device: UDP, TCP and serial (a device path or a fresh pty).

Each server turns what arrives into `sink(peer, data, datagram)` calls and gives every remote end a
peer object with `send(data)`. Nothing here knows the protocol.
"""

from __future__ import annotations

import asyncio
import os
import termios
import tty
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any, Protocol

Sink = Callable[[Any, bytes, bool], None]
BAUD = 115200
LOOPBACK = "127.0.0.1"


class Peer(Protocol):
    def send(self, data: bytes) -> None: ...


@dataclass(frozen=True)
class UdpPeer:
    """A UDP host: replies go to the address the request came from."""

    endpoint: UdpServer
    addr: tuple[Any, ...]

    def send(self, data: bytes) -> None:
        self.endpoint.sendto(data, self.addr)

    def __hash__(self) -> int:
        return hash((id(self.endpoint), self.addr))

    def __eq__(self, other: object) -> bool:
        return isinstance(other, UdpPeer) and other.endpoint is self.endpoint and other.addr == self.addr


class UdpServer(asyncio.DatagramProtocol):
    def __init__(self, sink: Sink) -> None:
        self.sink = sink
        self.transport: asyncio.DatagramTransport | None = None
        self.sent = 0

    def connection_made(self, transport: asyncio.BaseTransport) -> None:
        self.transport = transport  # type: ignore[assignment]

    def datagram_received(self, data: bytes, addr: tuple[Any, ...]) -> None:
        self.sink(UdpPeer(self, addr), data, True)

    def error_received(self, exc: Exception) -> None:
        pass  # ICMP "port unreachable" after a client went away: a device does not care either

    def sendto(self, data: bytes, addr: tuple[Any, ...]) -> None:
        if self.transport is not None and not self.transport.is_closing():
            self.transport.sendto(data, addr)
            self.sent += 1

    def close(self) -> None:
        if self.transport is not None:
            self.transport.close()

    @property
    def address(self) -> tuple[str, int]:
        assert self.transport is not None
        host, port = self.transport.get_extra_info("sockname")[:2]
        return host, port


class TcpPeer(asyncio.Protocol):
    """One TCP connection: a byte stream, replies and streams go back on it."""

    def __init__(self, sink: Sink, on_close: Callable[[TcpPeer], None]) -> None:
        self.sink = sink
        self.on_close = on_close
        self.transport: asyncio.Transport | None = None

    def connection_made(self, transport: asyncio.BaseTransport) -> None:
        self.transport = transport  # type: ignore[assignment]

    def data_received(self, data: bytes) -> None:
        self.sink(self, data, False)

    def connection_lost(self, exc: Exception | None) -> None:
        self.on_close(self)

    def send(self, data: bytes) -> None:
        if self.transport is not None and not self.transport.is_closing():
            self.transport.write(data)

    def close(self) -> None:
        if self.transport is not None:
            self.transport.close()


class TcpServer:
    def __init__(self, sink: Sink, forget: Callable[[Any], None]) -> None:
        self.sink = sink
        self.forget = forget
        self.server: asyncio.AbstractServer | None = None
        self.peers: set[TcpPeer] = set()

    async def start(self, host: str, port: int) -> None:
        loop = asyncio.get_running_loop()
        self.server = await loop.create_server(lambda: self._peer(), host, port)

    def _peer(self) -> TcpPeer:
        p = TcpPeer(self.sink, self._closed)
        self.peers.add(p)
        return p

    def _closed(self, peer: TcpPeer) -> None:
        self.peers.discard(peer)
        self.forget(peer)

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


def configure_tty(fd: int, baud: int = BAUD) -> None:
    """Raw 8N1 at `baud`: no echo, no line editing, no CR/LF translation."""
    tty.setraw(fd)
    attrs = termios.tcgetattr(fd)
    speed = getattr(termios, f"B{baud}", termios.B115200)
    attrs[4] = attrs[5] = speed
    attrs[2] = (
        (attrs[2] & ~(termios.PARENB | termios.CSTOPB | termios.CSIZE)) | termios.CS8 | termios.CREAD | termios.CLOCAL
    )
    termios.tcsetattr(fd, termios.TCSANOW, attrs)


class SerialPeer:
    """A serial line: a device path, or the master side of a pty pair whose slave a client opens."""

    def __init__(self, sink: Sink, device: str, baud: int = BAUD) -> None:
        self.sink = sink
        self.baud = baud
        self._slave_fd: int | None = None
        if device == "pty":
            self.fd, self._slave_fd = os.openpty()
            configure_tty(self.fd, baud)
            configure_tty(self._slave_fd, baud)
            self.path = os.ttyname(self._slave_fd)
        else:
            self.fd = os.open(device, os.O_RDWR | os.O_NOCTTY | os.O_NONBLOCK)
            configure_tty(self.fd, baud)
            self.path = device
        os.set_blocking(self.fd, False)
        self._pending = b""
        self._loop: asyncio.AbstractEventLoop | None = None

    def start(self) -> None:
        self._loop = asyncio.get_running_loop()
        self._loop.add_reader(self.fd, self._readable)

    def _readable(self) -> None:
        try:
            data = os.read(self.fd, 4096)
        except (BlockingIOError, InterruptedError):
            return
        except OSError:
            return  # pty without a reader on the other side (EIO): wait for the next client
        if data:
            self.sink(self, data, False)

    def send(self, data: bytes) -> None:
        # A pty buffer fills if nobody reads the slave; drop what does not fit rather than block
        # the event loop (a UART would overrun the same way).
        try:
            os.write(self.fd, data)
        except (BlockingIOError, InterruptedError, OSError):
            pass

    @property
    def url(self) -> str:
        return f"serial://{self.path}?baud={self.baud}"

    def close(self) -> None:
        if self._loop is not None:
            self._loop.remove_reader(self.fd)
        for fd in (self.fd, self._slave_fd):
            if fd is not None:
                try:
                    os.close(fd)
                except OSError:
                    pass
