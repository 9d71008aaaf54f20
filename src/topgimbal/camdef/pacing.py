"""One camera-definition download at a time: when to let a CAMERA_INFORMATION naming an HTTP URI out.

Why: MAVSDK 4.1 (the current C++ core under MAVSDK-Python 4.x) deadlocks when a CAMERA_INFORMATION
reaches it while it downloads a definition. Its camera plugin holds its mutex while it queues the
download (`CameraImpl::process_camera_information` -> `HttpLoader::download_async`, which locks the
work queue), and its HTTP thread holds that queue's lock for the whole download while its progress
callback waits for the plugin's mutex. The MAVLink receive thread then stops for good: no camera
list, no gimbal list, nothing more from that vehicle. A bridge with a visible and a thermal
camera answers MAVSDK's two CAMERA_INFORMATION requests within a millisecond, so the second one
arrives during the first download on almost every cold start (nothing in MAVSDK's cache, which is
every ground station's first connection). Seen here on 7 of 8 cold runs, 0 with a warm cache.

So the bridge lets such a message out only when the definition server is quiet (`quiet`): no
download open, none closed within `settle_s` (the client still finishes one after our last byte),
and no announced file still unfetched for `expect_s` (a client that has it cached never asks; after
that long we stop waiting for it). Each waiter is bounded by `max_hold_s`, after which it goes out
anyway with a log line: a late CAMERA_INFORMATION is better than none. The cost to a client that
does not need this (QGroundControl, a cached MAVSDK) is at most `expect_s` per camera, once.
`BridgeConfig.definition_one_at_a_time=False` (`topgimbal mavlink --definition-all-at-once`) turns
it off. docs/errata.md, "MAVSDK 4.1 and two camera definitions", has the record.
"""

from __future__ import annotations

import asyncio
import logging
from collections import deque
from typing import Protocol

from ..clock import MonotonicFn, monotonic

log = logging.getLogger("topgimbal.mavlink")

EXPECT_S = 1.5  # an announced file unfetched this long: the client will not ask (cached)
SETTLE_S = 0.5  # after a download's connection closed: the client's own end of it
MAX_HOLD_S = 10.0  # no message waits longer than this
FORGET_S = 60.0  # how long a file announced and not fetched counts as one the client has
POLL_S = 0.05


class Served(Protocol):
    """What the pacer reads from the definition server (http.DefinitionServer)."""

    active: int
    last_closed_at: float
    served_at: dict[str, float]


class FetchPacer:
    """One per MAVLink node: the cameras of every bridge on it (multi.py) share it, since a ground
    station hears all of them, and it watches each of their definition servers (`add`)."""

    def __init__(
        self,
        *servers: Served,
        expect_s: float = EXPECT_S,
        settle_s: float = SETTLE_S,
        max_hold_s: float = MAX_HOLD_S,
        clock: MonotonicFn = monotonic,
    ) -> None:
        self.servers = list(servers)
        self.expect_s = expect_s
        self.settle_s = settle_s
        self.max_hold_s = max_hold_s
        self.clock = clock
        self._expected: tuple[str, float] | None = None  # (file, when announced)
        # files announced and not fetched within expect_s: the client has them (or never fetches);
        # announced again within FORGET_S they are not waited for
        self._unfetched: dict[str, float] = {}
        self._queue: deque[object] = deque()  # waiters in turn order (first come, first out)
        self.held = 0  # messages that waited
        self.overdue = 0  # messages let out at max_hold_s, not quiet

    def add(self, server: Served) -> None:
        if all(s is not server for s in self.servers):  # by identity: two idle servers are equal
            self.servers.append(server)

    def quiet(self) -> bool:
        """Whether a CAMERA_INFORMATION may go out now; retires the expected file once it was
        fetched or expect_s passed (then remembered as one the client has)."""
        now, servers = self.clock(), self.servers
        if any(s.active > 0 or now - s.last_closed_at < self.settle_s for s in servers):
            return False
        if self._expected is not None:
            name, since = self._expected
            fetched = max((s.served_at.get(name, float("-inf")) for s in servers), default=float("-inf"))
            if fetched >= since:
                self._expected = None
            elif now - since >= self.expect_s:
                self._expected = None
                self._unfetched[name] = now
            else:
                return False
        return True

    def announce(self, name: str) -> None:
        """A CAMERA_INFORMATION naming `name` goes out now: its download may follow."""
        now = self.clock()
        self._unfetched = {n: t for n, t in self._unfetched.items() if now - t < FORGET_S}
        if name not in self._unfetched:
            self._expected = (name, now)

    async def turn(self, name: str) -> None:
        """Wait for this caller's turn (first come, first served) and a quiet server, at most
        max_hold_s in all, then announce `name`."""
        me = object()
        self._queue.append(me)
        try:
            if self._queue[0] is not me or not self.quiet():
                self.held += 1
                deadline = self.clock() + self.max_hold_s
                while self._queue[0] is not me or not self.quiet():
                    if self.clock() >= deadline:
                        self.overdue += 1
                        log.warning("camera definition %s: announced after %.1f s although a download may "
                                    "still run (a MAVSDK 4.1 client may stop answering; see docs/errata.md)",
                                    name, self.max_hold_s)  # fmt: skip
                        break
                    await asyncio.sleep(POLL_S)
            self.announce(name)
        finally:
            self._queue.remove(me)
