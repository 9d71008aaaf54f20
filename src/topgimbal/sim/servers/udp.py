"""UDP: one peer object per remote address, LRU-evicted at the cap, forgotten on ICMP "port
unreachable" (Linux IP_RECVERR) or after a lease; a send that would block is dropped."""

from __future__ import annotations

import asyncio
import errno
import socket
import struct
import sys
from collections.abc import Callable
from typing import Any

from ...clock import monotonic
from ...peers import EVICT, Gone, PeerTable, Words
from .common import MAX_DATAGRAM, READ_BATCH, Forget, Limits, Sink, Throttled, fmt_addr, listen_error

# Linux: with IP_RECVERR an unconnected UDP socket learns about ICMP errors, and the error queue
# (MSG_ERRQUEUE) names the destination each one is about. Python 3.11 has no constants for them.
IP_RECVERR = 11
IPV6_RECVERR = 25
SO_EE_ORIGIN_ICMP, SO_EE_ORIGIN_ICMP6 = 2, 3
UNREACHABLE = frozenset({errno.ECONNREFUSED, errno.EHOSTUNREACH, errno.ENETUNREACH, errno.EHOSTDOWN})
ERRQUEUE = sys.platform.startswith("linux") and hasattr(socket, "MSG_ERRQUEUE")
WORDS = Words(
    evicted="{name}: {count} peers (the limit, --max-udp-peers): forgetting the least recently heard, {peer} "
    "({age_s:.1f} s ago), and its streams"
)


class UdpPeer:
    """A UDP host: replies go to the address the request came from. One object per address while
    the server remembers it (its `peers` table keeps when it was last heard); a forgotten peer's
    sends are dropped."""

    __slots__ = ("addr", "endpoint", "gone")

    def __init__(self, endpoint: UdpServer, addr: tuple[Any, ...]) -> None:
        self.endpoint = endpoint
        self.addr = addr
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
        self, sink: Sink, forget: Forget, limits: Limits | None = None, clock: Callable[[], float] = monotonic
    ) -> None:
        self.sink = sink
        self.forget = forget
        self.limits = limits or Limits()
        self.clock = clock
        self.sock: socket.socket | None = None
        self.sent = 0
        self.dropped = 0  # sends that would have blocked or failed
        self.throttled = Throttled()
        # The shared peer table: LRU-evicted at the cap, leased; ICMP and the lease forget.
        self.peers: PeerTable[tuple[Any, ...], UdpPeer] = PeerTable(
            self.limits.max_udp_peers,
            at_cap=EVICT,
            lease_s=self.limits.udp_lease_s,
            clock=clock,
            name="udp",
            throttle=self.throttled,
            words=WORDS,
            describe=fmt_addr,
            on_gone=self._gone,
        )
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
        self._name = self.peers.name = f"udp {h}:{p}"
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
        peer = self.peers.heard(addr)  # renewed: the most recently heard now
        if peer is None:
            peer = UdpPeer(self, addr)
            self.peers.admit(addr, peer)  # at the cap the least recently heard goes (EVICT)
        self.sink(peer, data, True)

    @property
    def forgotten(self) -> dict[str, int]:
        """Peers forgotten so far, by why (the simulator's `server_counts`)."""
        t = self.peers
        return {"unreachable": t.forgotten, "lease": t.expired, "cap": t.evicted}

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
        self.throttled.warning("send", f"{self._name}: a datagram to {fmt_addr(peer.addr)} was dropped: {why}")

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
            if isinstance(addr, tuple) and (code is None or code in UNREACHABLE):
                self.peers.forget(addr)

    def _gone(self, gone: Gone[tuple[Any, ...], UdpPeer]) -> None:
        """Evicted, expired or unreachable: its sends stop, the simulator drops its streams."""
        peer = gone.value
        if not peer.gone:
            peer.gone = True
            self.forget(peer)

    def _arm_sweep(self) -> None:
        lease = self.limits.udp_lease_s
        if self._loop is None or lease <= 0:
            return
        self._sweep = self._loop.call_later(min(1.0, lease / 4), self._expire)

    def _expire(self) -> None:
        """Forget peers unheard for a lease."""
        self.peers.expire()
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
