"""UDP: one connected datagram socket to the device (the kernel filters other senders)."""

from __future__ import annotations

import asyncio
import logging
import socket

from ..errors import TransportError
from .base import Transport
from .udp_shared import SharedUdpSocket, shared_socket

log = logging.getLogger("topgimbal.transport")

# asyncio reads each datagram into a fresh 256 KiB buffer (CPython's `max_size`), which malloc
# serves with mmap and munmap: ~20 us a datagram, a third of a fleet server's CPU at 5000
# datagrams/s (bench/fleet.py). A UDP datagram holds at most 65,507 bytes (IPv4; 65,527 over
# IPv6): a 64 KiB buffer loses nothing and comes from the heap (~2.5 us).
MAX_DATAGRAM = 65536


class _Protocol(asyncio.DatagramProtocol):
    def __init__(self, owner: UdpTransport) -> None:
        self.owner = owner

    def datagram_received(self, data: bytes, addr: object) -> None:
        self.owner._on_bytes(data)

    def error_received(self, exc: Exception) -> None:
        # ICMP port unreachable while the device boots is not the end of a UDP "link": count, go on.
        self.owner.errors += 1

    def connection_lost(self, exc: Exception | None) -> None:
        self.owner._lost(exc)


SOCKET_KINDS = ("own", "shared")


class UdpTransport(Transport):
    """`udp://HOST:PORT[?local_port=N][&socket=own|shared]`; TOPOTEK devices answer to the sender's
    port, some firmware to 9004 only: `local_port` binds the local side for those. `socket=shared`
    puts this device on the event loop's one shared socket (transport/udp_shared.py: for a process
    with many cameras); not with `local_port`, which is a socket of its own by definition."""

    kind = "udp"
    is_datagram = True

    errors = 0
    _transport: asyncio.DatagramTransport | None = None
    _shared: SharedUdpSocket | None = None
    _peer: tuple[str, int] | None = None

    async def open(self) -> None:
        kind = self.url.params.get("socket", "own")
        if kind not in SOCKET_KINDS:
            raise TransportError(f"{self.url}: socket={kind!r}: expected one of {', '.join(SOCKET_KINDS)}")
        if kind == "shared":
            if "local_port" in self.url.params:
                raise TransportError(f"{self.url}: socket=shared and local_port exclude each other")
            if await self._open_shared():
                return
        loop = asyncio.get_running_loop()
        local = None
        if "local_port" in self.url.params:
            family_any = "::" if ":" in self.url.host else "0.0.0.0"
            local = (family_any, int(self.url.params["local_port"]))
        try:
            transport, _ = await loop.create_datagram_endpoint(
                lambda: _Protocol(self),
                remote_addr=(self.url.host, self.url.port or 0),
                local_addr=local,
                family=socket.AF_INET6 if ":" in self.url.host else socket.AF_INET,
            )
        except OSError as exc:
            raise TransportError(f"{self.url}: {exc}") from exc
        if isinstance(getattr(transport, "max_size", None), int):  # the selector loop's reader
            transport.max_size = MAX_DATAGRAM  # type: ignore[attr-defined]
        self._transport = transport

    async def _open_shared(self) -> bool:
        """On the loop's shared socket; False when another transport there has this device's
        address (then this one opens a socket of its own)."""
        loop = asyncio.get_running_loop()
        family = socket.AF_INET6 if ":" in self.url.host else socket.AF_INET
        try:
            infos = await loop.getaddrinfo(self.url.host, self.url.port or 0, family=family, type=socket.SOCK_DGRAM)
        except OSError as exc:
            raise TransportError(f"{self.url}: {exc}") from exc
        if not infos:
            raise TransportError(f"{self.url}: the host has no {family.name} address")
        addr = infos[0][4]
        peer = (str(addr[0]), int(addr[1]))
        shared = shared_socket(family)
        if not shared.register(peer, self._on_bytes):
            log.debug(
                "%s: another transport on the shared socket has %s:%s; using a socket of its own", self.url, *peer
            )
            return False
        self._shared, self._peer = shared, peer
        return True

    def send(self, data: bytes) -> None:
        self._check_open()
        if self._shared is not None:
            assert self._peer is not None
            self._shared.sendto(data, self._peer)
            return
        assert self._transport is not None
        self._transport.sendto(data)

    async def close(self) -> None:
        self._closed = True
        if self._shared is not None:
            assert self._peer is not None
            self._shared.unregister(self._peer, self._on_bytes)
            self._shared = None
        if self._transport is not None:
            self._transport.close()
            self._transport = None
