"""UDP sockets for the proxy, read in batches: every datagram waiting when the socket becomes
readable is handled in one callback (asyncio's datagram transport reads one per loop turn, which
lets a busy loop fall behind a 1,000 frames/s link). Non-blocking; nothing here waits."""

from __future__ import annotations

import asyncio
import socket
from collections.abc import Callable
from typing import Any

BATCH = 256  # datagrams read per wake-up at most (then other callbacks get their turn)
RCVBUF = 1 << 20  # bytes: room for a burst while the loop is busy


class UdpSocket:
    """One non-blocking UDP socket on the running loop; `on_datagram(data, addr)` per datagram."""

    def __init__(self, sock: socket.socket, on_datagram: Callable[[bytes, Any], None]) -> None:
        self.sock = sock
        self._on_datagram = on_datagram
        self.errors = 0
        self._loop = asyncio.get_running_loop()
        sock.setblocking(False)
        try:
            sock.setsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF, RCVBUF)
        except OSError:  # pragma: no cover - the kernel caps it; a smaller buffer still works
            pass
        self._loop.add_reader(sock.fileno(), self._readable)
        self._closed = False

    @classmethod
    async def bind(cls, host: str, port: int, on_datagram: Callable[[bytes, Any], None]) -> UdpSocket:
        return cls(await _socket(host, port, "bind"), on_datagram)

    @classmethod
    async def connect(cls, host: str, port: int, on_datagram: Callable[[bytes, Any], None]) -> UdpSocket:
        return cls(await _socket(host, port, "connect"), on_datagram)

    @property
    def address(self) -> tuple[str, int]:
        host, port = self.sock.getsockname()[:2]
        return str(host), int(port)

    @property
    def connected(self) -> bool:
        return not self._closed

    def _readable(self) -> None:
        for _ in range(BATCH):
            try:
                data, addr = self.sock.recvfrom(65536)
            except (BlockingIOError, InterruptedError):
                return
            except OSError:  # ICMP port unreachable on a connected socket: the peer is not up yet
                self.errors += 1
                continue
            self._on_datagram(data, addr)

    def send(self, data: bytes) -> None:
        """Send on a connected socket; a datagram the kernel cannot take now is dropped (UDP)."""
        try:
            self.sock.send(data)
        except OSError:
            self.errors += 1

    def sendto(self, data: bytes, addr: Any) -> None:
        try:
            self.sock.sendto(data, addr)
        except OSError:
            self.errors += 1

    async def close(self) -> None:
        if not self._closed:
            self._closed = True
            self._loop.remove_reader(self.sock.fileno())
            self.sock.close()


async def _socket(host: str, port: int, how: str) -> socket.socket:
    """A UDP socket bound to, or connected to, (host, port); OSError if that fails."""
    infos = await asyncio.get_running_loop().getaddrinfo(host, port, type=socket.SOCK_DGRAM)
    family, _, _, _, addr = infos[0]
    sock = socket.socket(family, socket.SOCK_DGRAM)
    try:
        getattr(sock, how)(addr)
    except OSError:
        sock.close()
        raise
    return sock
