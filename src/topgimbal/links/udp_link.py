"""udpin (listen: a peer is whoever sent something the node accepted, forgotten after
PEER_TIMEOUT_S of silence; at most max_peers) and udpout (send to one address, take what comes
back)."""

from __future__ import annotations

import asyncio
import logging
from collections.abc import Hashable
from typing import Any

from ..peers import EXPIRED, Gone
from .base import EndpointError, Link

log = logging.getLogger("topgimbal.mavlink")


class _UdpProtocol(asyncio.DatagramProtocol):
    def __init__(self, owner: UdpLink) -> None:
        self.owner = owner

    def datagram_received(self, data: bytes, addr: Any) -> None:
        self.owner._received(data, addr)

    def error_received(self, exc: Exception) -> None:
        # ICMP "port unreachable" from a ground station that is not running yet: not fatal.
        log.debug("%s: %s", self.owner, exc)


class UdpLink(Link):
    """udpin (listen) or udpout (send to a fixed address)."""

    def __init__(self, *a: Any, **kw: Any) -> None:
        super().__init__(*a, **kw)
        self._transport: asyncio.DatagramTransport | None = None

    @property
    def address(self) -> tuple[str, int] | None:
        if self._transport is None:
            return None
        name = self._transport.get_extra_info("sockname")
        return (str(name[0]), int(name[1])) if name else None

    @property
    def peer_count(self) -> int:
        return len(self.peers) if self.spec.kind == "udpin" else 1

    async def start(self) -> None:
        loop = asyncio.get_running_loop()
        try:
            if self.spec.kind == "udpin":
                self._transport, _ = await loop.create_datagram_endpoint(
                    lambda: _UdpProtocol(self), local_addr=(self.spec.host, self.spec.port)
                )
            else:
                self._transport, _ = await loop.create_datagram_endpoint(
                    lambda: _UdpProtocol(self), remote_addr=(self.spec.host, self.spec.port)
                )
        except OSError as exc:
            raise EndpointError(f"{self.spec}: {exc}") from exc

    def _received(self, data: bytes, addr: Any) -> None:
        if self.spec.kind != "udpin":
            self._deliver("out", data)
            return
        if addr in self.peers:
            if self._deliver(addr, data):
                self.peers.heard(addr)
            return
        self.peers.expire()
        if not self.peers.make_room(addr):
            return  # refused at the cap (counted and logged by the table)
        # A sender becomes a peer (a place, telemetry sent to it) only once the node accepts
        # something it sent: with a signing key, a signed message.
        if self._deliver(addr, data):
            log.info("%s: new peer %s", self, addr)
            self.peers.admit(addr, addr)

    def _gone(self, gone: Gone[Hashable, Any]) -> None:
        if gone.why == EXPIRED:
            log.info("%s: peer %s silent for %.0f s, forgotten", self, gone.key, self.peers.lease_s)
        super()._gone(gone)

    def send(self, data: bytes) -> None:
        t = self._transport
        if t is None or t.is_closing():
            self.dropped_out += 1
            return
        if self.spec.kind == "udpout":
            t.sendto(data)
            self.bytes_out += len(data)
            return
        self.peers.expire()
        for addr in self.peers.values():  # udpin: a peer's value is its address
            t.sendto(data, addr)
            self.bytes_out += len(data)

    def send_to(self, peer: Hashable, data: bytes) -> None:
        t = self._transport
        if self.spec.kind == "udpout" or t is None:
            self.send(data)
        elif peer in self.peers and not t.is_closing():
            t.sendto(data, peer)  # type: ignore[arg-type]  # a UDP address: a known peer
            self.bytes_out += len(data)

    async def close(self) -> None:
        self._closed = True
        if self._transport is not None:
            self._transport.close()
            self._transport = None
