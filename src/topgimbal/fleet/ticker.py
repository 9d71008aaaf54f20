"""One task for the periodic checks of every camera a process serves (issue 45).

Each served camera compares its state with what it last published (every STATE_POLL_S) and looks
for calls whose querier has left (every GONE_CHECK_S). As a task of its own per check, 1,000
cameras woke 6,000 tasks a second, most of them to find nothing to do: the wake-up cost more than
the check. Here one task runs them all, camera after camera; a camera whose check raises is
logged (at most every LOG_EVERY_S) and the others still run. A camera served alone (no
FleetServer) makes a ticker of its own.

The cameras are checked SLICE at a time, the loop's other work between two slices: all 1,000 in
one callback held the serving loop 3-4 ms four times a second, and every datagram that came then
waited that long before it was read (docs/fleet.md, "ninth round"). A camera removed while a tick
is under way is not checked again in it.
"""

from __future__ import annotations

import asyncio
import contextlib
import logging
from collections.abc import Callable
from typing import Protocol

from ..logthrottle import ThrottledLog

log = logging.getLogger("topgimbal.fleet")

LOG_EVERY_S = 10.0
SLICE = 50  # cameras checked in one loop callback: about 0.2 ms at a few us each


class Polled(Protocol):
    name: str

    def poll_state(self) -> None: ...

    def poll_gone(self) -> None: ...


class CameraTicker:
    """Runs `poll_state()` every `state_s` and `poll_gone()` every `gone_s` (rounded to a whole
    number of `state_s`) for every camera added, on the loop it was made on."""

    def __init__(self, state_s: float, gone_s: float) -> None:
        if not 0 < state_s <= gone_s:
            raise ValueError(f"state_s {state_s!r}, gone_s {gone_s!r}: expected 0 < state_s <= gone_s")
        self.state_s = state_s
        self.gone_every = max(1, round(gone_s / state_s))
        self._cams: dict[int, Polled] = {}  # by id: a camera is added once, in the order it came
        self._task: asyncio.Task[None] | None = None
        self._throttle = ThrottledLog(log, LOG_EVERY_S)
        self.failures = 0

    def add(self, cam: Polled) -> Callable[[], None]:
        """Poll `cam` from the next tick on; returns the function that stops it."""
        self._cams[id(cam)] = cam
        if self._task is None:
            self._task = asyncio.ensure_future(self._run())

        def remove() -> None:
            self._cams.pop(id(cam), None)

        return remove

    async def _run(self) -> None:
        tick = 0
        while True:
            await asyncio.sleep(self.state_s)
            tick += 1
            gone = tick % self.gone_every == 0
            cams = self._cams
            for i, (key, cam) in enumerate(list(cams.items())):
                if i and i % SLICE == 0:
                    await asyncio.sleep(0)  # the reads and puts waiting run now, not after every camera
                if cams.get(key) is not cam:
                    continue  # removed (closed) while an earlier slice waited
                try:
                    cam.poll_state()
                    if gone:
                        cam.poll_gone()
                except Exception:  # one camera's bug is not the others'
                    self.failures += 1
                    if self._throttle.allow("poll") is not None:
                        log.exception("%s: a periodic check failed (%d so far)", cam.name, self.failures)

    async def close(self) -> None:
        task, self._task = self._task, None
        if task is not None:
            task.cancel()
            with contextlib.suppress(asyncio.CancelledError):
                await task
