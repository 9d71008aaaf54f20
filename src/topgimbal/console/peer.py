"""One open page (WebSocket) and its bounded outgoing queue.

Each page is written to by its own task, so a slow page does not hold up the others; and what
waits for a page is bounded, so a browser tab that stops reading (a suspended laptop, a debugger
paused on a breakpoint) cannot grow the server's memory:

- periodic pushes (attitude, traffic, status) are dropped while more than `soft_limit` messages
  wait for the page (the next push replaces them; logged once per slow spell);
- replies to ops and error reports are never dropped: when one does not fit (more than
  `max_messages` messages or `max_bytes` bytes waiting), the page is disconnected at once (the
  connection is aborted, its buffers freed) with a log line; the page reconnects by itself.
"""

from __future__ import annotations

import asyncio
import logging
from collections import deque
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

from aiohttp import web

from ..client.jsonable import dumps as _dumps

log = logging.getLogger(__name__)

SOFT_LIMIT = 32  # messages waiting before periodic pushes are dropped (0.6 s of 50 Hz attitude)
MAX_MESSAGES = 512  # messages waiting before the page is disconnected
MAX_BYTES = 2 * 1024 * 1024  # bytes waiting before the page is disconnected


@dataclass(frozen=True)
class PeerLimits:
    """What may wait for one page (the module docstring says what happens at each limit)."""

    soft_limit: int = SOFT_LIMIT
    max_messages: int = MAX_MESSAGES
    max_bytes: int = MAX_BYTES


def dumps(obj: Mapping[str, Any]) -> str:
    """One push as text, by the SDK's one encoding (client/jsonable.py): NaN is null."""
    return _dumps(obj, separators=(",", ":"))


class Peer:
    """A page: `send()` queues (never blocks), `run()` writes the queue to the socket."""

    def __init__(
        self,
        ws: web.WebSocketResponse,
        name: str,
        *,
        limits: PeerLimits = PeerLimits(),
        transport: asyncio.Transport | None = None,
    ) -> None:
        self.ws = ws
        self.name = name
        self.limits = limits
        self.transport = transport
        self.queue: deque[str] = deque()
        self.queued_bytes = 0
        self.dropped = 0
        self.closed = False
        self.overflowed = False
        self._slow = False
        self._wakeup = asyncio.Event()

    def send(self, obj: Mapping[str, Any], *, essential: bool = True) -> None:
        if self.closed:
            return
        if not essential and len(self.queue) >= self.limits.soft_limit:
            self.dropped += 1
            if not self._slow:
                self._slow = True
                log.info("page %s is not keeping up: dropping periodic pushes while it catches up", self.name)
            return
        text = dumps(obj)
        if len(self.queue) >= self.limits.max_messages or self.queued_bytes + len(text) > self.limits.max_bytes:
            self._overflow()
            return
        self.queue.append(text)
        self.queued_bytes += len(text)
        self._wakeup.set()

    def _overflow(self) -> None:
        log.warning(
            "page %s stopped reading: %d messages (%d bytes) waiting, limits %d messages / %d bytes; disconnected",
            self.name,
            len(self.queue),
            self.queued_bytes,
            self.limits.max_messages,
            self.limits.max_bytes,
        )
        self.overflowed = True
        self.close()
        if self.transport is not None:
            self.transport.abort()  # close() would wait to flush to a page that does not read

    def close(self) -> None:
        """Stop sending (the writer task ends); queued messages are freed."""
        self.closed = True
        self.queue.clear()
        self.queued_bytes = 0
        self._wakeup.set()

    async def run(self) -> None:
        while not self.closed:
            if not self.queue:
                self._wakeup.clear()
                await self._wakeup.wait()
                continue
            text = self.queue.popleft()
            self.queued_bytes -= len(text)
            if not self.queue:
                self._slow = False
            if self.ws.closed:
                return
            try:
                await self.ws.send_str(text)
            except (ConnectionError, RuntimeError):
                return


__all__ = ["MAX_BYTES", "MAX_MESSAGES", "SOFT_LIMIT", "Peer", "dumps"]
