"""What the proxy has forwarded but not yet decoded: chunks wait here and are worked off through
the watcher DEFER_S after they were forwarded, in slices that end after PROCESS_SLICE_S or as soon
as a UDP socket of the proxy has a datagram waiting. So a reply is forwarded first, watching delays
the link by at most one chunk's decoding, and a burst is worked off between datagrams. Bounded:
beyond MAX_BACKLOG bytes, chunks are still forwarded but not decoded (counted, logged once)."""

from __future__ import annotations

import asyncio
import contextlib
import logging
import select
from collections import deque
from collections.abc import Iterator

from ..clock import monotonic
from .udplink import UdpSocket
from .watcher import Chunk, ProxyStats, Watcher

log = logging.getLogger("topgimbal.proxy")

MAX_BACKLOG = 1024 * 1024  # bytes forwarded but not yet decoded (decoding fell behind the link)
DEFER_S = 0.0002  # decoding starts this long after a chunk is forwarded (a loopback reply goes first)
PROCESS_SLICE_S = 0.0005  # decoding runs at most this long before the loop polls sockets again


class Backlog:
    def __init__(self, watcher: Watcher, stats: ProxyStats) -> None:
        self.watcher = watcher
        self.stats = stats
        self._chunks: deque[Chunk] = deque()
        self._bytes = 0
        self._poll = select.poll()
        self._drain_handle: asyncio.TimerHandle | None = None
        self._current: Iterator[bool] | None = None  # the chunk being worked off, step by step

    def queue(self, work: Chunk) -> None:
        size = len(work.data) + 64  # an empty chunk (a session's end, a flush) still costs an entry
        if self._bytes + size > MAX_BACKLOG:
            self.stats.backlog_dropped += 1
            if self.stats.backlog_dropped == 1:
                log.error("proxy: %d bytes wait to be decoded; skipping chunks (still forwarded)", MAX_BACKLOG)
            return
        self._bytes += size
        self._chunks.append(work)
        if self._drain_handle is None:
            self._drain_handle = asyncio.get_running_loop().call_later(DEFER_S, self._drain)

    def _drain(self) -> None:
        self._drain_handle = None
        end = monotonic() + PROCESS_SLICE_S
        while not self._bytes_waiting():
            if self._current is None:
                if not self._chunks:
                    break
                self._current = self.watcher.steps(self._take())
            if next(self._current, None) is None:
                self._current = None
            if monotonic() > end:
                break
        if self._chunks or self._current is not None:
            # A timer, not call_soon: asyncio runs the callbacks of sockets found readable before
            # the timers that fell due, so a waiting datagram is forwarded before decoding goes on
            # (a call_soon callback would run first and decode one more chunk).
            self._drain_handle = asyncio.get_running_loop().call_later(0, self._drain)

    def _bytes_waiting(self) -> bool:
        """Whether a UDP socket of the proxy has a datagram to forward (then decoding yields)."""
        try:
            # POLLIN or POLLERR (the loop's reader consumes both); never POLLNVAL, which a closed
            # descriptor would report forever and so stall decoding for good
            return any(ev & (select.POLLIN | select.POLLERR) for _, ev in self._poll.poll(0))
        except OSError:  # pragma: no cover - poll itself failed: decode on, the loop sorts sockets out
            return False

    def watch(self, sock: UdpSocket, on: bool = True) -> None:
        with contextlib.suppress(KeyError, ValueError, OSError):
            if on:
                self._poll.register(sock.sock.fileno(), select.POLLIN)
            else:
                self._poll.unregister(sock.sock.fileno())

    def drain(self) -> None:
        """Process everything that waits now (stop() does; tests and tools may too)."""
        if self._drain_handle is not None:
            self._drain_handle.cancel()
            self._drain_handle = None
        if self._current is not None:
            for _ in self._current:
                pass
            self._current = None
        while self._chunks:
            self.watcher.run(self._take())

    def _take(self) -> Chunk:
        work = self._chunks.popleft()
        self._bytes -= len(work.data) + 64
        return work
