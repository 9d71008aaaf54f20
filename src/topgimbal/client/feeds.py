"""What a host keeps sending because the model's profile says so (`host_feeds`: {ident: Hz}), and
the frames it sends once before (`host_setup`).

The C11 has no clock (TIM at 1 Hz, from the host's UTC clock, from the moment the client connects)
and takes the vehicle's attitude (FAE on once, then FAI at 10 Hz, once the program gives one with
`cam.vehicle_attitude(...)`). Which values a feed carries comes from its command's catalog role:
`time` is the host's clock, `vehicle_attitude` the last values given. A setup frame whose role is
`<role>_enable` goes out just before the feed of `<role>` starts, any other setup frame right after
connecting. Feeds are sent without waiting for an echo (the next one follows anyway); a feed that
fails is logged and retried at its next period. `connect(..., host_feeds=False)` turns all this off.
"""

from __future__ import annotations

import asyncio
import datetime
import logging
from collections.abc import Mapping
from typing import TYPE_CHECKING

from ..errors import TopGimbalError, UnsupportedError
from ..protocol import CommandSpec

if TYPE_CHECKING:
    from .core import ClientCore

log = logging.getLogger("topgimbal.client")

# Feeds the client can fill by itself, by catalog role.
CLOCK_ROLES = frozenset({"time", "utc_time"})
VEHICLE_ROLE = "vehicle_attitude"


class HostFeeds:
    def __init__(self, core: ClientCore) -> None:
        self.core = core
        self.enabled = core.options.host_feeds
        self.tasks: dict[str, asyncio.Task[None]] = {}
        self.values: dict[str, dict[str, object]] = {}  # ident -> what its feed carries now
        self.sent: dict[str, int] = {}  # frames sent per feed
        self._setup_done: set[str] = set()

    def _spec(self, ident: str) -> CommandSpec | None:
        core = self.core
        return core.dialect.commands.get(ident) if core.dialect.supports(core.model, ident) else None

    def feeds(self) -> dict[str, float]:
        """{ident: Hz} of the model's feeds that this dialect has."""
        return {i: hz for i, hz in self.core.model.host_feeds.items() if self._spec(i) is not None and hz > 0}

    async def start(self) -> None:
        """After connecting: the setup frames no feed waits for, then the clock feeds."""
        if not self.enabled:
            return
        feed_roles = {s.role for i in self.feeds() if (s := self._spec(i)) is not None}
        for ident, values in self.core.model.host_setup:
            spec = self._spec(ident)
            if spec is not None and spec.role.removesuffix("_enable") not in feed_roles:
                await self._setup(ident, values)
        for ident in self.feeds():
            spec = self._spec(ident)
            if spec is not None and spec.role in CLOCK_ROLES:
                self._start(ident)

    async def vehicle_attitude(self, values: Mapping[str, object]) -> None:
        """New vehicle attitude values: fed at the profile's rate where it names a feed (after
        its setup frames), else sent once and acknowledged."""
        core = self.core
        spec = core.dialect.by_role(VEHICLE_ROLE, core.model)
        if spec is None:
            raise UnsupportedError(f"the {core.model.name} takes no vehicle attitude")
        core.build_from(spec.ident, values)  # checked before anything changes
        if not self.enabled or spec.ident not in self.feeds():
            await core.send_request(core.build_from(spec.ident, values))
            return
        for ident, setup in core.model.host_setup:
            s = self._spec(ident)
            if s is not None and s.role == f"{spec.role}_enable":
                await self._setup(ident, setup)
        self.values[spec.ident] = dict(values)
        self._start(spec.ident)

    def stop(self) -> None:
        for task in self.tasks.values():
            task.cancel()
        self.tasks.clear()

    # -- internals -------------------------------------------------------------------------------

    async def _setup(self, ident: str, values: Mapping[str, object]) -> None:
        if ident in self._setup_done:
            return
        await self.core.send_request(self.core.build_from(ident, values))
        self._setup_done.add(ident)

    def _start(self, ident: str) -> None:
        task = self.tasks.get(ident)
        if task is None or task.done():
            self.tasks[ident] = asyncio.ensure_future(self._run(ident, 1.0 / self.feeds()[ident]))

    def _current(self, ident: str, spec: CommandSpec) -> dict[str, object] | None:
        if spec.role in CLOCK_ROLES:
            name = spec.forms_for("w", "request")[0].fields[0].name
            return {name: datetime.datetime.now(datetime.timezone.utc)}
        return self.values.get(ident)

    async def _run(self, ident: str, period_s: float) -> None:
        spec = self._spec(ident)
        assert spec is not None
        loop = asyncio.get_running_loop()
        next_at = loop.time()
        while True:
            values = self._current(ident, spec)
            if values is not None and self.core.connected:
                try:
                    self.core.send_nowait(self.core.build_from(ident, values))
                    self.sent[ident] = self.sent.get(ident, 0) + 1
                except TopGimbalError as exc:
                    log.info("%s: %s feed not sent: %s", self.core.url, ident, exc)
            next_at += period_s
            delay = next_at - loop.time()
            if delay < 0:  # fell behind (a busy loop): carry on from now, never in a burst
                next_at, delay = loop.time(), 0.0
            await asyncio.sleep(delay)
