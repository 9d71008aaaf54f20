"""Keeping the link: TCP / serial reconnection, and the harmless query that tells a quiet stream from
a dead device. The decisions are the pure link monitor's (link.py); this is their asyncio side,
driven by the client core through its `KeeperPort` (ports.py): a transition goes back to the core
(`on_link_event`), which carries it out (pending requests, streams, callbacks)."""

from __future__ import annotations

import asyncio
import contextlib
import logging

from ..errors import TopGimbalError, TransportError
from ..transport import open_transport
from . import roles
from .link import LinkEvent
from .ports import KeeperPort

log = logging.getLogger("topgimbal.client")


class LinkKeeper:
    def __init__(self, core: KeeperPort) -> None:
        self.core = core
        self.reconnect_task: asyncio.Task[None] | None = None
        self.ping_task: asyncio.Task[None] | None = None

    def event(self, event: LinkEvent | None) -> None:
        """Hand a transition the link monitor reported to the core, which carries it out."""
        if event is not None:
            self.core.on_link_event(event)

    def lost(self, exc: Exception | None) -> None:
        """The transport closed (TCP, serial; UDP only on local errors)."""
        core = self.core
        if core.closed or core.link is None:
            return
        self.event(core.link.on_closed(str(exc) if exc else "the link closed"))
        if core.options.reconnect_s is not None and self.reconnect_task is None:
            self.reconnect_task = asyncio.ensure_future(self._reconnect())

    async def _reconnect(self) -> None:
        """TCP and serial: reopen after a loss, backing off to 5 s between tries."""
        core = self.core
        delay = core.options.reconnect_s or 1.0
        try:
            while not core.closed:
                await asyncio.sleep(delay)
                try:
                    transport = await open_transport(core.transport_url, core.on_bytes, self.lost)
                except TransportError as exc:
                    log.info("%s: reconnect failed: %s", core.url, exc)
                    delay = min(5.0, delay * 2)
                    continue
                core.reopened(transport)
                assert core.link is not None
                self.event(core.link.on_opened())
                return
        finally:
            self.reconnect_task = None

    def maybe_ping(self, streaming: bool) -> None:
        """Requests in flight are probes already; a ping is for streams (`streaming`) that went quiet."""
        core, link = self.core, self.core.link
        if (
            link is not None
            and link.ping_due()
            and streaming
            and not core.busy
            and self.ping_task is None
            and core.connected_transport
        ):
            link.pinged()
            self.ping_task = asyncio.ensure_future(self._ping())

    async def _ping(self) -> None:
        """Ask something harmless: an answer tells a quiet stream from a dead device."""
        core = self.core
        try:
            ident = roles.ping_ident(core.dialect, core.model)
            if ident is not None:
                with contextlib.suppress(TopGimbalError):
                    await core.transact(core.build(ident, read=True), timeout_s=core.timeout_s, retries=0)
                    core.resume_streams()  # the device answers: make sure its stream is on
        finally:
            self.ping_task = None

    def stop(self) -> None:
        for task in (self.reconnect_task, self.ping_task):
            if task is not None:
                task.cancel()
