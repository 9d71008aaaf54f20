"""Keeping the link: what happens when it goes down or comes back, TCP / serial reconnection, and
the harmless query that tells a quiet stream from a dead device. The decisions are the pure link
monitor's (link.py); this is their asyncio side, driven by the client core."""

from __future__ import annotations

import asyncio
import contextlib
import logging
from typing import TYPE_CHECKING

from ..errors import LinkLostError, TopGimbalError, TransportError
from ..transport import open_transport
from . import roles
from .link import LinkEvent

if TYPE_CHECKING:
    from .core import ClientCore

log = logging.getLogger("topgimbal.client")


class LinkKeeper:
    def __init__(self, core: ClientCore) -> None:
        self.core = core
        self.reconnect_task: asyncio.Task[None] | None = None
        self.ping_task: asyncio.Task[None] | None = None

    def event(self, event: LinkEvent | None) -> None:
        """Carry out a transition the link monitor reported."""
        if event is None:
            return
        core = self.core
        core.stats.connected = core.connected
        if event.up:
            log.info("%s: link up (%s)", core.url, event.reason)
            core.streams.resume()
        else:
            core.stats.link_losses += 1
            log.warning("%s: link lost: %s", core.url, event.reason)
            err = LinkLostError(f"{core.url}: link lost: {event.reason}")
            core.fail_pending(err)
            core.streams.fail(err)
        core.notifier.link(event.up, event.reason)

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

    def maybe_ping(self) -> None:
        """Requests in flight are probes already; a ping is for streams that went quiet."""
        core, link = self.core, self.core.link
        if (
            link is not None
            and link.ping_due()
            and core.streams.active
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
                    await core._request(core.build(ident, read=True), timeout_s=core.timeout_s, retries=0)
                    core.streams.resume()  # the device answers: make sure its stream is on
        finally:
            self.ping_task = None

    def stop(self) -> None:
        for task in (self.reconnect_task, self.ping_task):
            if task is not None:
                task.cancel()
