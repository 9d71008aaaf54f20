"""One client's path through the proxy to the device (`Session`), the TCP client protocol that
feeds it, and the throttled warnings peers can trigger. The `Proxy` owns the sessions and does the
relaying, decoding and bookkeeping they call back into, seen here only through `SessionOwner`
(the few attributes and calls a session needs), so this module does not import the proxy's."""

from __future__ import annotations

import asyncio
import contextlib
import logging
from collections.abc import Callable, Hashable
from dataclasses import dataclass, field
from typing import Any, Protocol

from ..clock import monotonic
from ..errors import TopGimbalError, TransportError
from ..logthrottle import ThrottledLog
from ..protocol import FrameParser
from ..transport import Transport, TransportURL, open_transport
from ..transport.tcp import StreamTransport
from .packets import Endpoint
from .udplink import UdpSocket
from .watcher import IN, OUT

log = logging.getLogger("topgimbal.proxy")

MAX_QUEUED = 64 * 1024  # bytes waiting for a client's device link to open, or unread by a TCP client
LOG_EVERY_S = 10.0  # a warning that peers can repeat at will is logged at most this often


class Throttle(ThrottledLog):
    """Warnings a peer can trigger again and again (a flood of new clients or datagrams): each
    kind is logged at most once per LOG_EVERY_S, the next line saying how many were left out."""

    def __init__(self, every_s: float = LOG_EVERY_S, clock: Callable[[], float] = monotonic) -> None:
        super().__init__(log, every_s, clock)


class SessionOwner(Protocol):
    """What a session reads of the proxy that owns it, and the calls it makes back (wire/proxy.py)."""

    @property
    def listen(self) -> TransportURL: ...

    @property
    def to(self) -> TransportURL: ...

    @property
    def throttle(self) -> Throttle: ...

    def drop(self, session: Session, *, deliver: bool = False) -> None: ...

    def heard(self, session: Session) -> None: ...

    def tcp_connected(self, client: TcpClient) -> Session | None: ...

    def relay(self, session: Session, direction: str, data: bytes, send: Callable[[bytes], None]) -> None: ...

    def watch(self, sock: UdpSocket, on: bool = True) -> None: ...

    def session_closed(self, session: Session) -> None: ...


@dataclass
class Direction:
    """Decoding (and, from a stream to a datagram side, framing) of one direction of a session."""

    from_datagram: bool
    to_datagram: bool
    parser: FrameParser = field(default_factory=FrameParser)
    held: bytes = b""  # stream bytes the parser still holds (sent on when complete or stale)
    flush_timer: asyncio.TimerHandle | None = None


class Session:
    """One client's path to the device."""

    def __init__(
        self,
        proxy: SessionOwner,
        label: str,
        endpoint: Endpoint,
        send_down: Callable[[bytes], None],
        close_down: Callable[[], None] | None = None,
        pause_down: Callable[[bool], None] | None = None,
    ) -> None:
        self.proxy = proxy
        self.label = label
        self.endpoint = endpoint
        self.send_down = send_down
        self.close_down = close_down
        self.pause_down = pause_down  # a stream client: stop (True) or resume reading it
        self.paused = False
        self.upstream: Transport | UdpSocket | None = None
        self.queued: list[bytes] = []
        self.queued_bytes = 0
        self.closed = False
        self.key: Hashable | None = None  # its place in the proxy's client table, once admitted
        down_dgram = proxy.listen.scheme == "udp"
        up_dgram = proxy.to.scheme == "udp"
        self.dirs = {OUT: Direction(down_dgram, up_dgram), IN: Direction(up_dgram, down_dgram)}
        self.opening: asyncio.Task[None] | None = None

    async def open(self) -> None:
        to = self.proxy.to
        try:
            if to.scheme == "udp":
                self.upstream = await UdpSocket.connect(to.host, to.port or 0, self._device_datagram)
                self.proxy.watch(self.upstream)
            else:
                self.upstream = await open_transport(to, self.from_device, self.device_lost)
        except (OSError, TopGimbalError) as exc:
            self.proxy.throttle.warning("unreachable", "proxy: cannot reach %s for %s: %s", to, self.label, exc)
            self.proxy.drop(self)
            return
        queued, self.queued, self.queued_bytes = self.queued, [], 0
        for chunk in queued:
            self._send_up(chunk)
        if self.paused and self.pause_down is not None:
            self.paused = False
            self.pause_down(False)

    def from_client(self, data: bytes) -> None:
        if self.upstream is None:
            if self.pause_down is not None:
                # A stream's bytes cannot be dropped (the frames around the hole would be cut):
                # the client is not read until the link opens, so at most one read more waits.
                self.queued.append(data)
                self.queued_bytes += len(data)
                if self.queued_bytes > MAX_QUEUED and not self.paused:
                    log.warning(
                        "proxy: %s: %d bytes wait for the device link; not reading this client until it opens",
                        self.label,
                        self.queued_bytes,
                    )
                    self.paused = True
                    self.pause_down(True)
                return
            if self.queued_bytes + len(data) > MAX_QUEUED:
                self.proxy.throttle.warning(
                    "queue full",
                    "proxy: %s: %d bytes already wait for the device link; dropping %d",
                    self.label,
                    self.queued_bytes,
                    len(data),
                )
                return
            self.queued.append(data)
            self.queued_bytes += len(data)
            return
        self._send_up(data)

    def _send_up(self, data: bytes) -> None:
        self.proxy.relay(self, OUT, data, self._upstream_send)

    def _upstream_send(self, data: bytes) -> None:
        if self.upstream is not None and self.upstream.connected:
            unsent = self.upstream.write_buffer_size if isinstance(self.upstream, StreamTransport) else 0
            if unsent > MAX_QUEUED:
                # the device stopped reading: this session ends rather than buffering without bound
                log.warning("proxy: %s: the device has %d unread bytes; closing this client", self.label, unsent)
                self.proxy.drop(self)
                return
            try:
                self.upstream.send(data)
            except TransportError as exc:
                self.proxy.throttle.warning("send failed", "proxy: %s: device link: %s", self.label, exc)

    def _device_datagram(self, data: bytes, addr: Any) -> None:
        self.from_device(data)

    def from_device(self, data: bytes) -> None:
        self.proxy.heard(self)  # a client that only listens to a stream is active too
        self.proxy.relay(self, IN, data, self.send_down)

    def device_lost(self, exc: Exception | None) -> None:
        if not self.closed:
            log.info("proxy: device link of %s closed%s", self.label, f": {exc}" if exc else "")
            self.proxy.drop(self)

    async def close(self, deliver: bool = False) -> None:
        """End the session. `deliver`: the client left (a command sent and the connection closed
        at once, as `nc -q0` does): what it sent before the device link opened still goes to the
        device, once the link is up."""
        if self.closed:
            return
        self.closed = True
        for d in self.dirs.values():
            if d.flush_timer is not None:
                d.flush_timer.cancel()
        if self.opening is not None and not self.opening.done():
            if deliver and self.queued:
                with contextlib.suppress(asyncio.CancelledError):
                    await self.opening  # open() sends what waits; bounded by the link's connect timeout
            else:
                self.opening.cancel()
        if self.close_down is not None:
            self.close_down()
        self.proxy.session_closed(self)
        if self.upstream is not None:
            if isinstance(self.upstream, UdpSocket):
                self.proxy.watch(self.upstream, on=False)
            await self.upstream.close()


class TcpClient(asyncio.Protocol):
    def __init__(self, proxy: SessionOwner) -> None:
        self.proxy = proxy
        self.session: Session | None = None
        self.transport: asyncio.Transport | None = None

    def connection_made(self, transport: asyncio.BaseTransport) -> None:
        self.transport = transport  # type: ignore[assignment]
        self.session = self.proxy.tcp_connected(self)

    def data_received(self, data: bytes) -> None:
        if self.session is not None:
            self.session.from_client(data)

    def connection_lost(self, exc: Exception | None) -> None:
        if self.session is not None:
            self.proxy.drop(self.session, deliver=True)

    def send(self, data: bytes) -> None:
        if self.transport is None or self.transport.is_closing():
            return
        if self.transport.get_write_buffer_size() > MAX_QUEUED:
            # The client stopped reading: it is dropped rather than buffered without bound. abort(),
            # not close(): close() waits for the unread bytes to leave, which they never do, and
            # the session would keep its client slot for good.
            self.proxy.throttle.warning(
                "unread", "proxy: a TCP client has %d unread bytes; closing it", self.transport.get_write_buffer_size()
            )
            self.transport.abort()
            if self.session is not None:
                self.proxy.drop(self.session)
            return
        self.transport.write(data)

    def close(self) -> None:
        if self.transport is not None:
            self.transport.close()

    def pause(self, paused: bool) -> None:
        if self.transport is not None and not self.transport.is_closing():
            if paused:
                self.transport.pause_reading()
            else:
                self.transport.resume_reading()


def ep_text(addr: tuple[Any, ...]) -> str:
    host, port = str(addr[0]), addr[1]
    return f"[{host}]:{port}" if ":" in host else f"{host}:{port}"
