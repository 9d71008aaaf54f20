"""Thin asyncio transports around the device: UDP, TCP and serial (a device path or a fresh pty).

Each server turns what arrives into `sink(peer, data, datagram)` calls and gives every remote end a
peer object with `send(data)`. Nothing here knows the protocol.

Every resource a remote end can make the server hold is bounded (`Limits`, docs/simulator.md
"Limits"): UDP peers (LRU-evicted at the cap, forgotten on ICMP "port unreachable" or after a lease
without a datagram), TCP clients (refused at the cap) and each TCP client's unsent bytes (a client
that does not read is dropped at the high-water mark). A UDP send that would block is dropped, as a
congested link drops it: nothing is ever queued in user space for UDP.
"""

from __future__ import annotations

import asyncio
import errno
import logging
import os
import socket
import struct
import sys
import termios
import time
import tty
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

from ..errors import TopGimbalError

Sink = Callable[[Any, bytes, bool], None]
Forget = Callable[[Any], None]
BAUD = 115200
LOOPBACK = "127.0.0.1"
MAX_DATAGRAM = 2048  # the longest TOP frame is ~270 bytes; several may share one datagram
READ_BATCH = 64  # datagrams read per wake-up: one selector round trip serves a burst
TCP_READ_CHUNK = 2048  # bytes taken from one TCP client per turn (several frames)
TCP_PAUSE_READING_BYTES = 4096  # replies backed up beyond this: stop reading that client's requests

log = logging.getLogger("topgimbal.sim")


class ListenError(TopGimbalError, OSError):
    """A listening socket could not be bound; the message names the address and what to do."""


@dataclass(frozen=True)
class Limits:
    """What one remote end, or all of them, can make a simulator hold (docs/simulator.md)."""

    udp_lease_s: float = 60.0  # forget a UDP peer (and its streams) after this long unheard; 0 = never
    max_udp_peers: int = 64  # per UDP endpoint; the least recently heard is forgotten at the cap
    max_tcp_clients: int = 64  # per TCP endpoint; further connections are closed at once
    tcp_buffer_bytes: int = 64 * 1024  # unsent bytes per TCP client before it is dropped
    tcp_sndbuf_bytes: int = 64 * 1024  # kernel send buffer per TCP client (SO_SNDBUF)

    def __post_init__(self) -> None:
        for name in ("max_udp_peers", "max_tcp_clients", "tcp_buffer_bytes", "tcp_sndbuf_bytes"):
            if getattr(self, name) < 1:
                raise ValueError(f"{name}={getattr(self, name)!r}: expected 1 or more")
        if not self.udp_lease_s >= 0:
            raise ValueError(f"udp_lease_s={self.udp_lease_s!r}: expected seconds >= 0 (0 = no lease)")


class Throttled:
    """One log line per key per `interval_s`; the next one says how many were held back."""

    def __init__(self, interval_s: float = 10.0) -> None:
        self.interval_s = interval_s
        self._last: dict[str, float] = {}
        self._held: dict[str, int] = {}

    def warning(self, key: str, message: str) -> None:
        now = time.monotonic()
        last = self._last.get(key)
        if last is not None and now - last < self.interval_s:
            self._held[key] = self._held.get(key, 0) + 1
            return
        held = self._held.pop(key, 0)
        self._last[key] = now
        log.warning("%s%s", message, f" ({held} more like this since the last report)" if held else "")


def listen_error(kind: str, host: str, port: int, exc: OSError) -> ListenError:
    """A bind failure as one line a user can act on."""
    if exc.errno == errno.EADDRINUSE:
        hint = f"another program (or simulator) has it; use {host}:0 for any free port"
        what = "address already in use"
    elif exc.errno == errno.EACCES:
        hint = f"ports below 1024 need privileges; use {host}:0 for any free port"
        what = "permission denied"
    else:
        hint, what = "use 127.0.0.1:0 for any free loopback port", exc.strerror or str(exc)
    err = ListenError(f"cannot listen on {kind} {host}:{port}: {what} ({hint})")
    err.errno = exc.errno
    return err


# -- UDP -------------------------------------------------------------------------------------------

# Linux: with IP_RECVERR an unconnected UDP socket learns about ICMP errors, and the error queue
# (MSG_ERRQUEUE) names the destination each one is about. Python 3.11 has no constants for them.
IP_RECVERR = 11
IPV6_RECVERR = 25
SO_EE_ORIGIN_ICMP, SO_EE_ORIGIN_ICMP6 = 2, 3
UNREACHABLE = frozenset({errno.ECONNREFUSED, errno.EHOSTUNREACH, errno.ENETUNREACH, errno.EHOSTDOWN})
ERRQUEUE = sys.platform.startswith("linux") and hasattr(socket, "MSG_ERRQUEUE")


class UdpPeer:
    """A UDP host: replies go to the address the request came from. One object per address while
    the server remembers it; a forgotten peer's sends are dropped."""

    __slots__ = ("addr", "endpoint", "gone", "heard")

    def __init__(self, endpoint: UdpServer, addr: tuple[Any, ...], heard: float) -> None:
        self.endpoint = endpoint
        self.addr = addr
        self.heard = heard
        self.gone = False

    def send(self, data: bytes) -> None:
        if not self.gone:
            self.endpoint.sendto(data, self)

    def __repr__(self) -> str:
        return f"UdpPeer({self.addr[0]}:{self.addr[1]})"


class UdpServer:
    """One UDP socket read and written directly (no asyncio transport: it would queue sends
    without bound and hides which address an ICMP error is about)."""

    def __init__(
        self, sink: Sink, forget: Forget, limits: Limits | None = None, clock: Callable[[], float] = time.monotonic
    ) -> None:
        self.sink = sink
        self.forget = forget
        self.limits = limits or Limits()
        self.clock = clock
        self.sock: socket.socket | None = None
        self.peers: dict[tuple[Any, ...], UdpPeer] = {}  # in order of last datagram, oldest first
        self.sent = 0
        self.dropped = 0  # sends that would have blocked or failed
        self.forgotten = {"unreachable": 0, "lease": 0, "cap": 0}
        self.throttled = Throttled()
        self._loop: asyncio.AbstractEventLoop | None = None
        self._sweep: asyncio.TimerHandle | None = None
        self._name = "udp"

    async def start(self, host: str, port: int) -> None:
        self._loop = asyncio.get_running_loop()
        family = socket.AF_INET6 if ":" in host else socket.AF_INET
        sock = socket.socket(family, socket.SOCK_DGRAM)
        try:
            sock.setblocking(False)
            sock.bind((host, port))
        except OSError as exc:
            sock.close()
            raise listen_error("udp", host, port, exc) from None
        if ERRQUEUE:
            level, opt = (
                (socket.IPPROTO_IPV6, IPV6_RECVERR) if family == socket.AF_INET6 else (socket.IPPROTO_IP, IP_RECVERR)
            )
            try:
                sock.setsockopt(level, opt, 1)
            except OSError:
                pass  # then only the lease and the cap apply
        self.sock = sock
        h, p = self.address
        self._name = f"udp {h}:{p}"
        self._loop.add_reader(sock.fileno(), self._readable)
        self._arm_sweep()

    def _readable(self) -> None:
        sock = self.sock
        if sock is None:
            return
        for i in range(READ_BATCH):
            try:
                data, addr = sock.recvfrom(MAX_DATAGRAM)
            except (BlockingIOError, InterruptedError):
                if i == 0:
                    self._drain_errors()  # woken by the error queue alone (EPOLLERR)
                return
            except OSError as exc:
                # A pending ICMP error surfaces on the next call; the error queue says for whom.
                if exc.errno in UNREACHABLE:
                    self._drain_errors()
                continue
            self._datagram(data, addr)

    def _datagram(self, data: bytes, addr: tuple[Any, ...]) -> None:
        now = self.clock()
        peer = self.peers.pop(addr, None)
        if peer is None:
            if len(self.peers) >= self.limits.max_udp_peers:
                oldest = next(iter(self.peers.values()))
                self.throttled.warning(
                    "cap",
                    f"{self._name}: {len(self.peers)} peers (the limit, --max-udp-peers): forgetting the "
                    f"least recently heard, {_fmt(oldest.addr)} ({now - oldest.heard:.1f} s ago), and its streams",
                )
                self._drop(oldest, "cap")
            peer = UdpPeer(self, addr, now)
        else:
            peer.heard = now
        self.peers[addr] = peer  # re-inserted: the dict stays in order of last datagram
        self.sink(peer, data, True)

    def sendto(self, data: bytes, peer: UdpPeer) -> None:
        sock = self.sock
        if sock is None:
            return
        try:
            sock.sendto(data, peer.addr)
            self.sent += 1
            return
        except (BlockingIOError, InterruptedError):
            self._dropped(peer, "the socket's send buffer is full")
            return
        except OSError as exc:
            if exc.errno not in UNREACHABLE:
                self._dropped(peer, exc.strerror or str(exc))
                return
        # An earlier ICMP error (perhaps about another peer) failed this send: learn whom it was
        # about, then send once more unless it was about this peer.
        self._drain_errors()
        if peer.gone:
            return
        try:
            sock.sendto(data, peer.addr)
            self.sent += 1
        except OSError as exc:
            self._dropped(peer, exc.strerror or str(exc))

    def _dropped(self, peer: UdpPeer, why: str) -> None:
        self.dropped += 1
        self.throttled.warning("send", f"{self._name}: a datagram to {_fmt(peer.addr)} was dropped: {why}")

    def _drain_errors(self, limit: int = 4096) -> None:
        """Forget every peer the error queue says is unreachable (Linux IP_RECVERR)."""
        sock = self.sock
        if sock is None or not ERRQUEUE:
            return
        for _ in range(limit):
            try:
                _, ancdata, _, addr = sock.recvmsg(1, 512, socket.MSG_ERRQUEUE)
            except (BlockingIOError, InterruptedError):
                return
            except OSError:
                return
            code = _extended_errno(ancdata)
            peer = self.peers.get(addr) if isinstance(addr, tuple) else None
            if peer is not None and (code is None or code in UNREACHABLE):
                self._drop(peer, "unreachable")

    def _drop(self, peer: UdpPeer, why: str) -> None:
        if self.peers.get(peer.addr) is peer:
            del self.peers[peer.addr]
        if not peer.gone:
            peer.gone = True
            self.forgotten[why] += 1
            self.forget(peer)

    def _arm_sweep(self) -> None:
        lease = self.limits.udp_lease_s
        if self._loop is None or lease <= 0:
            return
        self._sweep = self._loop.call_later(min(1.0, lease / 4), self._expire)

    def _expire(self) -> None:
        """Forget peers unheard for a lease (the dict is oldest first: stop at the first fresh one)."""
        limit = self.clock() - self.limits.udp_lease_s
        while self.peers:
            peer = next(iter(self.peers.values()))
            if peer.heard > limit:
                break
            self._drop(peer, "lease")
        self._arm_sweep()

    def close(self) -> None:
        if self._sweep is not None:
            self._sweep.cancel()
            self._sweep = None
        if self.sock is not None:
            if self._loop is not None:
                self._loop.remove_reader(self.sock.fileno())
            self.sock.close()
            self.sock = None

    @property
    def address(self) -> tuple[str, int]:
        assert self.sock is not None
        host, port = self.sock.getsockname()[:2]
        return host, port


def _extended_errno(ancdata: list[tuple[int, int, bytes]]) -> int | None:
    """ee_errno of the `struct sock_extended_err` in an error-queue message, if there is one."""
    for level, kind, data in ancdata:
        if (level, kind) in ((socket.IPPROTO_IP, IP_RECVERR), (socket.IPPROTO_IPV6, IPV6_RECVERR)) and len(data) >= 8:
            ee_errno, origin = struct.unpack_from("=IB", data)
            if origin in (SO_EE_ORIGIN_ICMP, SO_EE_ORIGIN_ICMP6):
                return int(ee_errno)
            return -1  # not an ICMP report (e.g. a local error): keep the peer
    return None


def _fmt(addr: tuple[Any, ...]) -> str:
    host, port = addr[:2]
    return f"[{host}]:{port}" if ":" in str(host) else f"{host}:{port}"


# -- TCP -------------------------------------------------------------------------------------------


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
        self.name = f"tcp client {_fmt(transport.get_extra_info('peername') or ('?', 0))}"
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
        self.peers: set[TcpPeer] = set()
        self.refused = 0
        self.overflows = 0
        self.max_unsent = 0  # the most bytes held for one client when it was dropped
        self.throttled = Throttled()
        self._name = "tcp"

    async def start(self, host: str, port: int) -> None:
        loop = asyncio.get_running_loop()
        try:
            self.server = await loop.create_server(lambda: TcpPeer(self), host, port)
        except OSError as exc:
            raise listen_error("tcp", host, port, exc) from None
        h, p = self.address
        self._name = f"tcp {h}:{p}"

    def opened(self, peer: TcpPeer) -> None:
        t = peer.transport
        assert t is not None
        if len(self.peers) >= self.limits.max_tcp_clients:
            self.refused += 1
            self.throttled.warning(
                "cap",
                f"{self._name}: {len(self.peers)} clients (the limit, --max-tcp-clients): closing the new "
                f"connection from {peer.name.removeprefix('tcp client ')}",
            )
            t.abort()
            return
        sock = t.get_extra_info("socket")
        if sock is not None:
            try:
                sock.setsockopt(socket.SOL_SOCKET, socket.SO_SNDBUF, self.limits.tcp_sndbuf_bytes)
            except OSError:
                pass
        t.set_write_buffer_limits(high=min(TCP_PAUSE_READING_BYTES, self.limits.tcp_buffer_bytes), low=0)
        self.peers.add(peer)

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
        if peer in self.peers:
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


# -- serial ----------------------------------------------------------------------------------------


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
