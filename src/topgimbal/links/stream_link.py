"""tcp (connect out, reconnect with back-off), tcpin (listen: at most max_peers connections, one
silent for PEER_TIMEOUT_S closed when a new one needs its place) and serial (reopened when it
fails): one byte stream per peer, each bounded in what it queues (MAX_WRITE_BUFFER)."""

from __future__ import annotations

import asyncio
import contextlib
import logging
from collections.abc import Hashable
from typing import Any

from ..peers import EXPIRED, Gone
from ..timeouts import within
from .base import MAX_UNTRUSTED_BYTES, MAX_WRITE_BUFFER, RECONNECT_MAX_S, RECONNECT_MIN_S, EndpointError, Link

log = logging.getLogger("topgimbal.mavlink")


class _StreamProtocol(asyncio.Protocol):
    def __init__(self, owner: StreamLink, peer: Hashable) -> None:
        self.owner = owner
        self.peer = peer
        self.transport: asyncio.Transport | None = None
        self.trusted = False  # the node accepted something it sent
        self.untrusted_bytes = 0

    def connection_made(self, transport: asyncio.BaseTransport) -> None:
        self.transport = transport  # type: ignore[assignment]
        self.owner._connected(self)

    def data_received(self, data: bytes) -> None:
        self.owner.peers.heard(self.peer)  # anything renews the place, signed or not
        if self.owner._deliver(self.peer, data):
            self.trusted = True
        else:
            self.owner._untrusted(self, len(data))

    def connection_lost(self, exc: Exception | None) -> None:
        self.owner._disconnected(self, exc)


class StreamLink(Link):
    """tcp (connect out, reconnect), tcpin (listen) and serial (reopen): one byte stream per peer."""

    def __init__(self, *a: Any, **kw: Any) -> None:
        super().__init__(*a, **kw)
        self._server: asyncio.base_events.Server | None = None
        self._task: asyncio.Task[None] | None = None
        self._lost = asyncio.Event()
        self._serial_n = 0

    @property
    def address(self) -> tuple[str, int] | None:
        if self._server is None or not self._server.sockets:
            return None
        name = self._server.sockets[0].getsockname()
        return (str(name[0]), int(name[1]))

    @property
    def peer_count(self) -> int:
        return len(self.peers)

    async def start(self) -> None:
        loop = asyncio.get_running_loop()
        if self.spec.kind == "tcpin":
            try:
                self._server = await loop.create_server(self._accept, self.spec.host, self.spec.port)
            except OSError as exc:
                raise EndpointError(f"{self.spec}: {exc}") from exc
            return
        self._task = asyncio.ensure_future(self._keep_open())

    def _accept(self) -> asyncio.Protocol:
        self._serial_n += 1
        return _StreamProtocol(self, ("tcpin", self._serial_n))

    async def _open_once(self) -> None:
        loop = asyncio.get_running_loop()
        self._serial_n += 1
        peer = (self.spec.kind, self._serial_n)
        if self.spec.kind == "tcp":
            await within(
                loop.create_connection(lambda: _StreamProtocol(self, peer), self.spec.host, self.spec.port), 5.0
            )
            return
        try:
            import serial_asyncio_fast
        except ImportError:  # pragma: no cover - depends on the installation
            raise EndpointError(
                "serial MAVLink links need pyserial-asyncio-fast: pip install 'topgimbal[serial]'"
            ) from None
        await serial_asyncio_fast.create_serial_connection(
            loop, lambda: _StreamProtocol(self, peer), self.spec.device, baudrate=self.spec.baud
        )

    async def _keep_open(self) -> None:
        delay = RECONNECT_MIN_S
        while not self._closed:
            self._lost.clear()
            try:
                await self._open_once()
            except EndpointError as exc:
                log.error("%s", exc)
                return
            except (OSError, asyncio.TimeoutError, ValueError) as exc:
                log.info("%s: cannot open (%s); retrying in %.1f s", self, exc or "timed out", delay)
                await asyncio.sleep(delay)
                delay = min(RECONNECT_MAX_S, delay * 2)
                continue
            delay = RECONNECT_MIN_S
            await self._lost.wait()
            if not self._closed:
                await asyncio.sleep(RECONNECT_MIN_S)

    def _gone(self, gone: Gone[Hashable, Any]) -> None:
        """tcpin: a connection nothing was heard from for PEER_TIMEOUT_S is closed (as udpin forgets
        silent peers; the table's lease, applied when a new one needs the place and before each
        send): a ground station sends a heartbeat every second, and silent connections must not
        keep new ground stations out for good."""
        if gone.why == EXPIRED:
            log.info("%s: %s silent for %.0f s, closed", self, gone.key, self.peers.lease_s)
            if gone.value.transport is not None:
                gone.value.transport.close()
        super()._gone(gone)

    def _connected(self, proto: _StreamProtocol) -> None:
        if not self.peers.admit(proto.peer, proto):
            if proto.transport is not None:  # refused at the cap (counted and logged by the table)
                proto.transport.close()
            return
        log.info("%s: connected (%s)", self, proto.peer)

    def _disconnected(self, proto: _StreamProtocol, exc: Exception | None) -> None:
        if self.peers.get(proto.peer) is proto:
            log.info("%s: %s closed%s", self, proto.peer, f" ({exc})" if exc else "")
            self.peers.forget(proto.peer)
        if self.spec.kind != "tcpin":
            self._lost.set()

    def _untrusted(self, proto: _StreamProtocol, n: int) -> None:
        """tcpin with a signing key: a connection that sent MAX_UNTRUSTED_BYTES with nothing signed
        among them is closed (its place freed)."""
        if not self.needs_trust or self.spec.kind != "tcpin" or proto.trusted:
            return
        proto.untrusted_bytes += n
        if proto.untrusted_bytes <= MAX_UNTRUSTED_BYTES:
            return
        self.untrusted_closed += 1
        if self._refusal_log.allow("untrusted") is not None:
            log.warning("%s: %s sent %d bytes and nothing signed with the key: closed (%d refused so far)", self,
                        proto.peer, proto.untrusted_bytes, self.refused_peers)  # fmt: skip
        self.peers.forget(proto.peer, proto)
        if proto.transport is not None:
            proto.transport.close()

    def _serves(self, proto: _StreamProtocol) -> bool:
        return proto.trusted or not self.needs_trust or self.spec.kind != "tcpin"

    def send(self, data: bytes) -> None:
        self.peers.expire()
        if not self.peers:
            self.dropped_out += 1
            return
        for proto in list(self.peers.values()):
            t = proto.transport
            if t is None or t.is_closing() or not self._serves(proto):
                continue
            if t.get_write_buffer_size() > MAX_WRITE_BUFFER:
                self.dropped_out += 1  # a peer that does not read loses messages, not our memory
                continue
            t.write(data)
            self.bytes_out += len(data)

    def send_to(self, peer: Hashable, data: bytes) -> None:
        proto = self.peers.get(peer)
        t = None if proto is None or not self._serves(proto) else proto.transport
        if t is None or t.is_closing() or t.get_write_buffer_size() > MAX_WRITE_BUFFER:
            self.dropped_out += 1
            return
        t.write(data)
        self.bytes_out += len(data)

    async def close(self) -> None:
        self._closed = True
        self._lost.set()
        if self._task is not None:
            self._task.cancel()
            with contextlib.suppress(asyncio.CancelledError, Exception):
                await self._task
        for proto in self.peers.clear():
            if proto.transport is not None:
                proto.transport.close()
        if self._server is not None:
            self._server.close()
            with contextlib.suppress(Exception):
                await self._server.wait_closed()
            self._server = None
