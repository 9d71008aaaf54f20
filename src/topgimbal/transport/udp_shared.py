"""Many UDP devices on one socket: `udp://HOST:PORT?socket=shared` (issue 45).

A process that serves hundreds of cameras (`topgimbal zenoh`) with one connected socket each pays
the event loop's per-socket price for every datagram: a readiness event, a Handle, a transport
callback, a 64 KiB read buffer. At 1,000 cameras x 50 Hz that was more than half of the serving
loop's CPU (bench/fleet.py under py-spy). Here the cameras of one event loop share one unconnected
socket per address family: one readiness event drains up to READ_BATCH datagrams into one reused
buffer, and each goes to the transport registered for its source address (ip, port).

What a connected socket gives, this keeps: datagrams from any other address are dropped (counted
in `strangers`), and a camera's replies must come from the address it was sent to. What it does
not: ICMP "port unreachable" is not reported per camera (an unconnected socket hears none), which
the client never needed (a UDP link is judged by what arrives, client/link.py). Two transports to
the same device address cannot share (whose reply would it be?): the second gets a socket of its
own. The socket's receive buffer asks for RCVBUF_BYTES because it holds what a thousand
per-camera buffers held: with CAP_NET_ADMIN (SO_RCVBUFFORCE) it gets them, else the kernel caps
it at net.core.rmem_max. A datagram that does not fit is lost, as on a full per-camera buffer, and
the kernel counts it: that count (SO_MEMINFO, Linux) is read at most once a second while datagrams
arrive, added to `kernel_dropped` and said in a throttled warning, since a loop that fell behind
by that much is what a user must hear about (bench/fleet.py saw it under a full 2-core machine).

A loaded socket is read on a timer, not per datagram (NAPI's idea). At 1,000 cameras x 50 Hz a
readiness event found 3 datagrams on average: 16,000 wake-ups of the loop a second, each an
epoll_wait, a loop turn and a read, each sample paying a third of one. When one event
finds POLL_ENTER or more waiting, the reader is removed and the socket is read every POLL_S
(about a millisecond: the loop's selector waits whole milliseconds) while each read finds at least
POLL_STAY, at once again when a read stops at READ_BATCH (a backlog), and by readiness events again
when traffic falls below that (about 4,000 datagrams a second). In alternating runs it took the
server's CPU a sample from 18.0-18.2 to 16.2-16.3 us, for about 1.4 ms more of median wait
(docs/fleet.md, eighth round).

One SharedUdpSocket per (event loop, family); it closes with its last transport.
"""

from __future__ import annotations

import asyncio
import logging
import socket
import struct
import sys
import weakref
from collections.abc import Callable

from .. import _speedups as speedups
from ..clock import loop_clock
from ..errors import TransportError
from ..logthrottle import ThrottledLog

log = logging.getLogger("topgimbal.transport")

READ_BATCH = 256  # datagrams read per readiness event, then the loop runs its other callbacks
MAX_DATAGRAM = 65536  # a UDP datagram holds at most 65,507 bytes (IPv4), 65,527 (IPv6)
# The kernel doubles what is asked and charges 832 bytes per small datagram (bench/fleet.py measures
# it): 32 MiB counted is about 0.8 s of 1,000 cameras at 50 Hz queued before the server reads them.
RCVBUF_BYTES = 16 * 1024 * 1024
SO_MEMINFO = 55  # Linux: u32 sk_meminfo[]; Python has no constant for it
SO_RCVBUFFORCE = 33  # Linux; Python names it from 3.12 on
SK_MEMINFO_DROPS = 8  # the receive queue's drops, in that array
DROP_CHECK_S = 1.0
RECV_MANY = 64  # datagrams a recvmmsg call reads at most (the C extension's limit)
POLL_ENTER = 4  # a readiness event that finds this many datagrams: read on a timer from then
POLL_STAY = 4  # ... while each timed read finds at least this many
POLL_S = 0.001  # the timed read's period (asyncio's selector waits whole milliseconds)
Route = Callable[[bytes], None]
Addr = tuple[str, int]
RecvMany = Callable[[int, int], list[tuple[bytes, Addr | None]]]

_SHARED: weakref.WeakKeyDictionary[asyncio.AbstractEventLoop, dict[int, SharedUdpSocket]] = weakref.WeakKeyDictionary()


def shared_socket(family: int) -> SharedUdpSocket:
    """The running loop's shared socket for `family` (AF_INET or AF_INET6), made on first use."""
    loop = asyncio.get_running_loop()
    per_loop = _SHARED.setdefault(loop, {})
    shared = per_loop.get(family)
    if shared is None or shared.closed:
        shared = per_loop[family] = SharedUdpSocket(loop, family)
    return shared


class SharedUdpSocket:
    def __init__(self, loop: asyncio.AbstractEventLoop, family: int) -> None:
        self.loop = loop
        self.family = family
        self.routes: dict[Addr, Route] = {}
        self.closed = False
        self.received = 0
        self.strangers = 0  # datagrams from an address no transport here sends to
        self.send_dropped = 0  # sends the kernel refused (a full send buffer): UDP's own loss
        self.read_errors = 0
        self.kernel_dropped = 0  # datagrams the kernel dropped: a full receive buffer (SO_MEMINFO)
        self._drops_seen: int | None = None  # the kernel's count at the last look (None: cannot read it)
        self._now = loop_clock(loop)
        self._next_drop_check = 0.0
        self._poll_handle: asyncio.Handle | None = None  # the next timed read, while polling
        self.polls_started = 0  # times the socket went from readiness events to timed reads
        self._buf = bytearray(MAX_DATAGRAM)
        self._view = memoryview(self._buf)
        # recvmmsg where the C extension has it (Linux, IPv4): the same datagrams in the same order,
        # read and routed in 0.88 us each instead of 1.51 (one process, docs/fleet.md); else
        # recvfrom_into, one system call a datagram.
        self._recv_many = speedups.recv_many() if family == socket.AF_INET else None
        self._throttle = ThrottledLog(log, 10.0)
        sock = socket.socket(family, socket.SOCK_DGRAM)
        try:
            sock.setblocking(False)
            sock.bind(("::" if family == socket.AF_INET6 else "0.0.0.0", 0))
            _ask_rcvbuf(sock, RCVBUF_BYTES)
            self._drops_seen = _kernel_drops(sock)
            loop.add_reader(sock.fileno(), self._readable)
        except OSError as exc:
            sock.close()
            raise TransportError(f"cannot open a shared UDP socket: {exc}") from exc
        self.sock = sock

    @property
    def local_address(self) -> Addr:
        host, port = self.sock.getsockname()[:2]
        return str(host), int(port)

    def register(self, addr: Addr, route: Route) -> bool:
        """Deliver datagrams from `addr` to `route`; False when another transport has `addr`."""
        if self.closed or addr in self.routes:
            return False
        self.routes[addr] = route
        return True

    def unregister(self, addr: Addr, route: Route) -> None:
        if self.routes.get(addr) is route:
            del self.routes[addr]
        if not self.routes:
            self.close()

    def sendto(self, data: bytes, addr: Addr) -> bool:
        """False when the datagram was not sent (a full send buffer, an unreachable network)."""
        try:
            self.sock.sendto(data, addr)
            return True
        except (BlockingIOError, InterruptedError):
            why = "the socket's send buffer is full"
        except OSError as exc:
            why = exc.strerror or str(exc)
        self.send_dropped += 1
        self._throttle.warning("send", "shared UDP socket: a datagram to %s:%s was dropped: %s", addr[0], addr[1], why)
        return False

    @property
    def polling(self) -> bool:
        """Whether the socket is read on a timer now (a loaded socket), not by readiness events."""
        return self._poll_handle is not None

    def _readable(self) -> None:
        started = self._now()
        n = self._read()
        if n >= POLL_ENTER and not self.closed and self._poll_handle is None:
            self.loop.remove_reader(self.sock.fileno())
            self._poll_handle = self.loop.call_at(started + POLL_S, self._poll)
            self.polls_started += 1

    def _poll(self) -> None:
        """A timed read; then the next one, or readiness events again once traffic is light (the
        reader is level-triggered: what came meanwhile wakes it at once)."""
        self._poll_handle = None
        if self.closed:
            return
        started = self._now()
        n = 0  # a read that raised: readiness events again (then the loop logs the error)
        try:
            n = self._read()
        finally:
            if not self.closed:
                self._next_read(started, n)

    def _next_read(self, started: float, n: int) -> None:
        if n >= READ_BATCH:  # a backlog: on at once, after the loop's other callbacks
            self._poll_handle = self.loop.call_soon(self._poll)
        elif n >= POLL_STAY:
            # POLL_S from this read's start, not its end: a read of 100 datagrams takes 1-2 ms, and
            # a datagram would wait that long more (350-590 reads a second measured, not 1,000)
            self._poll_handle = self.loop.call_at(started + POLL_S, self._poll)
        else:
            self.loop.add_reader(self.sock.fileno(), self._readable)

    def _read(self) -> int:
        """Reads and routes what is queued, at most READ_BATCH datagrams; returns how many it took
        off the queue (strangers and failed reads included)."""
        if self._drops_seen is not None and self._now() >= self._next_drop_check:
            self._check_drops()
        if self._recv_many is not None:
            return self._read_many(self._recv_many)
        sock, view, routes = self.sock, self._view, self.routes
        taken = 0
        for _ in range(READ_BATCH):
            try:
                n, addr = sock.recvfrom_into(self._buf)
            except (BlockingIOError, InterruptedError):
                return taken
            except OSError as exc:  # nothing is expected here (no ICMP without IP_RECVERR): count, go on
                taken += 1
                self.read_errors += 1
                self._throttle.warning("read", "shared UDP socket: read failed: %s", exc)
                continue
            taken += 1
            route = routes.get(addr[:2])
            if route is None:
                self.strangers += 1
                continue
            self.received += 1
            try:
                route(bytes(view[:n]))
            except Exception:  # one camera's bug is not the others'
                log.exception("shared UDP socket: the handler for %s:%s failed", addr[0], addr[1])
            if self.closed:  # that camera was the last one and closed in its handler
                return taken
        return taken

    def _read_many(self, recv_many: RecvMany) -> int:
        """`_read` with recvmmsg (the C fast path): RECV_MANY datagrams a system call, in the
        order the kernel queued them, each delivered as the loop above delivers it."""
        fd, routes = self.sock.fileno(), self.routes
        taken = 0
        for _ in range(READ_BATCH // RECV_MANY):
            try:
                got = recv_many(fd, RECV_MANY)
            except OSError as exc:  # as above: nothing is expected here
                taken += 1
                self.read_errors += 1
                self._throttle.warning("read", "shared UDP socket: read failed: %s", exc)
                continue
            taken += len(got)
            for data, addr in got:
                route = routes.get(addr) if addr is not None else None
                if route is None:
                    self.strangers += 1
                    continue
                self.received += 1
                try:
                    route(data)
                except Exception:  # one camera's bug is not the others'
                    log.exception("shared UDP socket: the handler for %s:%s failed", addr[0], addr[1])  # type: ignore[index]
                if self.closed:  # that camera was the last one and closed in its handler
                    return taken
            if len(got) < RECV_MANY:  # the queue is empty (or was, a moment ago): back to the loop
                return taken
        return taken

    def _check_drops(self) -> None:
        self._next_drop_check = self._now() + DROP_CHECK_S
        now = _kernel_drops(self.sock)
        if now is None or self._drops_seen is None:
            return
        new, self._drops_seen = (now - self._drops_seen) % 2**32, now  # the kernel's u32 wraps
        if new:
            self.kernel_dropped += new
            rcvbuf = self.sock.getsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF)
            self._throttle.warning("kernel", "shared UDP socket: the kernel dropped %d datagrams from the cameras "
                                   "(%d in all): its receive buffer (%d bytes) was full while this process was busy; "
                                   "give it more (net.core.rmem_max, or run with CAP_NET_ADMIN) or fewer cameras per "
                                   "process (topgimbal zenoh --workers)", new, self.kernel_dropped, rcvbuf)  # fmt: skip

    def close(self) -> None:
        if self.closed:
            return
        self.closed = True
        self.routes.clear()
        if self._poll_handle is not None:
            self._poll_handle.cancel()
            self._poll_handle = None
        if not self.loop.is_closed():
            self.loop.remove_reader(self.sock.fileno())
        self.sock.close()


def _ask_rcvbuf(sock: socket.socket, size: int) -> None:
    """`size` bytes of receive buffer: forced past net.core.rmem_max where allowed (CAP_NET_ADMIN),
    else as much as that limit lets."""
    force = getattr(socket, "SO_RCVBUFFORCE", SO_RCVBUFFORCE if sys.platform.startswith("linux") else None)
    for opt in (force, socket.SO_RCVBUF):
        if opt is None:
            continue
        try:
            sock.setsockopt(socket.SOL_SOCKET, opt, size)
            return
        except OSError:
            continue  # not allowed (no CAP_NET_ADMIN): the capped request, else the system's default


def _kernel_drops(sock: socket.socket) -> int | None:
    """The kernel's count of datagrams dropped on `sock`'s receive queue (Linux), else None."""
    if not sys.platform.startswith("linux"):
        return None
    try:
        raw = sock.getsockopt(socket.SOL_SOCKET, SO_MEMINFO, 4 * (SK_MEMINFO_DROPS + 1))
    except OSError:
        return None
    if len(raw) < 4 * (SK_MEMINFO_DROPS + 1):
        return None
    return int(struct.unpack_from("I", raw, 4 * SK_MEMINFO_DROPS)[0])
