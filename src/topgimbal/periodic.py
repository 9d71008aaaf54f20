"""One step every period, from `start()` until `close()`: the loop of the bridge's parts that act on
a timer (autopilot/streams.py asks for what is missing, mavlink/camera_feed.py feeds the camera). `close()`
cancels it and waits until it has ended, so nothing of a closed bridge is left running; a step that
raised is logged once (it ended the loop) rather than raised out of `close()`, which would leave the
bridge's later parts open."""

from __future__ import annotations

import asyncio
import contextlib
import logging
from collections.abc import Awaitable, Callable

log = logging.getLogger("topgimbal.mavlink")


class Periodic:
    def __init__(self, period_s: float, step: Callable[[], Awaitable[None]], *, name: str) -> None:
        """`step` is awaited every `period_s` (the first after one period); `name` is for the log."""
        self.period_s = period_s
        self.step = step
        self.name = name
        self._task: asyncio.Task[None] | None = None

    @property
    def started(self) -> bool:
        return self._task is not None

    def start(self) -> None:
        if self._task is None:
            self._task = asyncio.ensure_future(self._run())

    async def close(self) -> None:
        task, self._task = self._task, None
        if task is None:
            return
        task.cancel()
        with contextlib.suppress(asyncio.CancelledError):
            try:
                await task
            except Exception:
                log.exception("%s stopped on an error", self.name)

    async def _run(self) -> None:
        while True:
            await asyncio.sleep(self.period_s)
            await self.step()
