"""MAVLink links in pymavlink's connection-string syntax, on asyncio.

    udpin:HOST:PORT    listen; answer every peer heard in the last PEER_TIMEOUT_S (at most max_peers)
    udp:HOST:PORT      the same as udpin (as in pymavlink)
    udpout:HOST:PORT   send to HOST:PORT, take what comes back
    tcp:HOST:PORT      connect; reconnect with back-off when the peer goes away
    tcpin:HOST:PORT    listen; at most max_peers connections at once; one silent for PEER_TIMEOUT_S
                       is closed when a new one needs its place (or when we next send)
    DEVICE[,BAUD]      a serial port (/dev/ttyUSB0,57600; default 115200); reopened when it fails
    memory:NAME        in-process (tests, embedding): peers connect by NAME (memory_link.py)

Links carry bytes only; the node parses MAVLink per (link, peer) so a stream split anywhere is
reassembled. Every buffer is bounded: peers per link, bytes queued per connection."""

from __future__ import annotations

import abc
import asyncio
import contextlib
import logging
import re
from collections.abc import Callable, Hashable
from dataclasses import dataclass
from typing import Any

from ..errors import TopGimbalError
from ..logthrottle import ThrottledLog
from ..peers import EXPIRED, REFUSE, Gone, PeerTable, Words
from ..timeouts import within

log = logging.getLogger("topgimbal.mavlink")

MAX_PEERS = 16
PEER_TIMEOUT_S = 30.0
MAX_WRITE_BUFFER = 256 * 1024
# tcpin with a signing key: bytes a connection may send with nothing signed among them before it is
# closed (a MAVLink 2 signed frame is at most 280 bytes; a few unsigned heartbeats pass under it)
MAX_UNTRUSTED_BYTES = 4096
# The peer table's refusal line (peers.py; throttled, one per 10 s, the next one counting the rest).
WORDS = Words(refused="{name}: already {cap} peers (the limit); ignoring {newcomer}")
RECONNECT_MIN_S = 0.5
RECONNECT_MAX_S = 5.0
DEFAULT_BAUD = 115200

# Returns False when nothing in the bytes was accepted (a signing key is set and none was signed
# with it): a UDP sender is then no peer. None or True: accepted.
DataCallback = Callable[["Link", Hashable, bytes], "bool | None"]
GoneCallback = Callable[["Link", Hashable], None]


class EndpointError(TopGimbalError, ValueError):
    """A MAVLink connection string that cannot be used."""


@dataclass(frozen=True)
class EndpointSpec:
    kind: str  # udpin, udpout, tcp, tcpin, serial, memory (NAME in device)
    host: str = ""
    port: int = 0
    device: str = ""
    baud: int = DEFAULT_BAUD
    text: str = ""

    def __str__(self) -> str:
        return self.text


FORMS = "udpin:HOST:PORT, udpout:HOST:PORT, tcp:HOST:PORT, tcpin:HOST:PORT, a serial DEVICE[,BAUD] or memory:NAME"
MEMORY_NAME = re.compile(r"[A-Za-z0-9][A-Za-z0-9._-]{0,63}")
# Link kinds whose module builds on this one (memory_link.py registers "memory" when imported, as
# node.py does): made here all the same, without an import circle.
LINK_KINDS: dict[str, Callable[[EndpointSpec, DataCallback, GoneCallback, int], Link]] = {}


def parse_endpoint(text: str) -> EndpointSpec:
    """Parse one pymavlink-style connection string; EndpointError says what is allowed."""
    if not isinstance(text, str) or not text.strip():
        raise EndpointError(f"empty MAVLink endpoint: expected {FORMS}")
    s = text.strip()
    scheme, sep, rest = s.partition(":")
    scheme = scheme.lower()
    if sep and scheme in ("udp", "udpin", "udpout", "tcp", "tcpin"):
        host, _, port_text = rest.rpartition(":")
        host = host.strip("[]")
        if not host or not port_text.isdigit() or not 0 <= int(port_text) <= 65535:
            raise EndpointError(f"{text!r}: expected {scheme}:HOST:PORT (port 0..65535)")
        port = int(port_text)
        kind = "udpin" if scheme == "udp" else scheme
        if kind in ("udpout", "tcp") and port == 0:
            raise EndpointError(f"{text!r}: {kind} needs the peer's port, not 0")
        return EndpointSpec(kind, host, port, text=s)
    if sep and scheme == "memory":
        if not MEMORY_NAME.fullmatch(rest):
            raise EndpointError(f"{text!r}: expected memory:NAME (1..64 letters, digits, '.', '_', '-'; "
                                "a letter or digit first)")  # fmt: skip
        return EndpointSpec("memory", device=rest, text=s)
    if scheme in ("udpbcast", "mcast", "wsserver", "ws", "wss"):
        raise EndpointError(f"{text!r}: {scheme}: links are not supported; use {FORMS}")
    device, baud = s, DEFAULT_BAUD
    for sep_char in (",", "@"):
        if sep_char in s:
            device, _, baud_text = s.rpartition(sep_char)
            if not baud_text.isdigit():
                raise EndpointError(f"{text!r}: baud {baud_text!r} is not a number")
            baud = int(baud_text)
            break
    if not (device.startswith("/") or device.upper().startswith("COM")):
        raise EndpointError(f"{text!r}: not a MAVLink endpoint; expected {FORMS}")
    return EndpointSpec("serial", device=device, baud=baud, text=s)


class Link(abc.ABC):
    """One MAVLink link: bytes in through `on_data(link, peer, data)`, `send()` to every peer."""

    def __init__(self, spec: EndpointSpec, on_data: DataCallback, on_gone: GoneCallback, max_peers: int) -> None:
        self.spec = spec
        self._on_data = on_data
        self._on_gone = on_gone
        self.max_peers = max_peers
        self.bytes_in = 0
        self.bytes_out = 0
        self.dropped_out = 0
        self.untrusted_closed = 0  # tcpin with a signing key: connections closed for sending nothing signed
        # Set by a node with a signing key: a listening link then serves only senders whose bytes
        # it accepted (udpin: no peer place, tcpin: no telemetry, closed after MAX_UNTRUSTED_BYTES).
        self.needs_trust = False
        self._closed = False
        self._refusal_log = ThrottledLog(log, 10.0)  # a peer flood: one line per 10 s
        # The shared peer table (peers.py): at most max_peers, a newcomer refused at the cap; on a
        # listening link one silent for PEER_TIMEOUT_S gives its place back (udpin: forgotten,
        # tcpin: closed). Values: udpin the address, streams their connection.
        listening = spec.kind in ("udpin", "tcpin", "memory")
        self.peers: PeerTable[Hashable, Any] = PeerTable(
            max_peers,
            at_cap=REFUSE,
            lease_s=PEER_TIMEOUT_S if listening else 0.0,
            name=spec.text,
            throttle=self._refusal_log,
            words=WORDS,
            on_gone=self._gone,
        )

    @property
    def refused_peers(self) -> int:
        """Peers turned away: at the cap, or (tcpin with a signing key) for sending nothing signed."""
        return self.peers.refused + self.untrusted_closed

    def _gone(self, gone: Gone[Hashable, Any]) -> None:
        """A peer left the table (silent for the lease, closed, or untrusted): the node forgets it."""
        self._on_gone(self, gone.key)

    def __str__(self) -> str:
        return self.spec.text

    @property
    def address(self) -> tuple[str, int] | None:
        """The local (host, port) a listening link is bound to (port 0 resolved)."""
        return None

    @property
    @abc.abstractmethod
    def peer_count(self) -> int: ...

    @abc.abstractmethod
    async def start(self) -> None: ...

    @abc.abstractmethod
    def send(self, data: bytes) -> None: ...

    @abc.abstractmethod
    async def close(self) -> None: ...

    def send_to(self, peer: Hashable, data: bytes) -> None:
        """To one peer (a reply only it asked for); links that cannot address one send to all."""
        self.send(data)

    def _deliver(self, peer: Hashable, data: bytes) -> bool:
        """Whether the node accepted anything in `data` (see DataCallback)."""
        self.bytes_in += len(data)
        try:
            return self._on_data(self, peer, data) is not False
        except Exception:  # one bad packet must not end the link
            log.exception("%s: handling %d bytes from %s failed", self, len(data), peer)
            return False


# -- UDP ---------------------------------------------------------------------------------------------


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


# -- streams (TCP, serial) ---------------------------------------------------------------------------


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


def make_link(
    spec: EndpointSpec | str, on_data: DataCallback, on_gone: GoneCallback, max_peers: int = MAX_PEERS
) -> Link:
    spec = parse_endpoint(spec) if isinstance(spec, str) else spec
    if spec.kind in LINK_KINDS:
        return LINK_KINDS[spec.kind](spec, on_data, on_gone, max_peers)
    cls: type[Link] = UdpLink if spec.kind in ("udpin", "udpout") else StreamLink
    return cls(spec, on_data, on_gone, max_peers)
