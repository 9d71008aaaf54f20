"""Many cameras' attitude samples in one Zenoh put: `topgimbal/@attitude/<server id>` (issue 45).

A subscriber of every camera's `topgimbal/<name>/attitude` gets one Zenoh sample, and runs one
callback, per camera per frame: 50,000 a second for 1,000 cameras at 50 Hz, more than a Python
program keeps up with beside its server, and each one costs the server a put to that subscriber.
The batch key carries the same samples, each the per-camera JSON with the camera's `name` first,
as one JSON array per put: every `batch_s` (the first sample of a batch starts the wait, so a
sample waits at most that long) or at once when MAX_SAMPLES are waiting.

The key's second chunk starts with '@': a verbatim chunk in Zenoh, which no wildcard matches, so
a subscriber of `topgimbal/**` (a console, a recorder) never gets batches it did not ask for.
Subscribe to `topgimbal/@attitude/*`: one key per serving process (its Zenoh session id), so
`topgimbal zenoh --workers K` puts K batch streams. The per-camera keys are published as before.
"""

from __future__ import annotations

import asyncio
import logging
from typing import Any

from ..client.remote_keys import ROOT
from ..logthrottle import ThrottledLog

log = logging.getLogger("topgimbal.fleet")

BATCH_CHUNK = "@attitude"
BATCH_KEYS = f"{ROOT}/{BATCH_CHUNK}/*"  # what a subscriber of every server's batches asks for
# 2 ms: at 1,000 cameras x 50 Hz, 540 puts a second instead of 5 ms's 190, for 0.3-0.4 us more of the
# server's CPU a sample (18.2 against 17.8-17.9) and half the wait (a sample's median from camera
# to subscriber 1.3-1.6 ms instead of 2.9-3.4; docs/fleet.md, 2026-11-30)
DEFAULT_BATCH_S = 0.002
MIN_BATCH_S, MAX_BATCH_S = 0.001, 1.0
MAX_SAMPLES = 4096  # samples in one put at most (about 450 KiB): more are put at once


def batch_key(server_id: str) -> str:
    return f"{ROOT}/{BATCH_CHUNK}/{server_id}"


def named(name: str, sample_json: str) -> str:
    """A camera's attitude JSON (`{"yaw_deg":...}`) with `"name"` first. Camera names are checked
    on the way in (remote_keys.NAME_RE: letters, digits, '_', '-', '.'), so nothing needs escaping."""
    return f'{{"name":"{name}",{sample_json[1:]}'


class AttitudeBatch:
    """Collects samples on the serving loop and puts them as one JSON array. Sync, loop-bound: `add`
    is called from the cameras' attitude taps, on the loop the batch was made on."""

    def __init__(self, session: Any, server_id: str, batch_s: float = DEFAULT_BATCH_S) -> None:
        if not MIN_BATCH_S <= batch_s <= MAX_BATCH_S:
            raise ValueError(f"batch_s {batch_s!r}: expected {MIN_BATCH_S}..{MAX_BATCH_S} s")
        self.key = batch_key(server_id)
        self.batch_s = batch_s
        self._loop = asyncio.get_running_loop()
        self._pub = session.declare_publisher(self.key)
        self._lines: list[str] = []
        self._first_t: float | None = None  # when the first sample waiting arrived (add's `t`)
        self._timer: asyncio.TimerHandle | None = None
        self._closed = False
        self.puts = 0
        self.samples = 0
        self.failed = 0  # puts Zenoh refused (a closing session): their samples are not sent
        self._throttle = ThrottledLog(log, 10.0)

    def add(self, line: str, t: float | None = None) -> None:
        """`t`: when the sample arrived, on the loop's clock. A sample that comes when the batch's
        first one has waited `batch_s` already puts the batch at once: while the loop reads a
        burst of datagrams (256 at a time, several milliseconds in a busy worker) the timer cannot
        run, and the batch would wait for the whole burst."""
        if self._closed:
            return
        lines = self._lines
        lines.append(line)
        if len(lines) == 1:
            self._first_t = t
        if len(lines) >= MAX_SAMPLES or (
            t is not None and self._first_t is not None and t - self._first_t >= self.batch_s
        ):
            self.flush()
        elif self._timer is None:
            self._timer = self._loop.call_later(self.batch_s, self.flush)

    def flush(self) -> None:
        if self._timer is not None:
            self._timer.cancel()
            self._timer = None
        lines = self._lines
        if not lines:
            return
        self._lines = []
        try:
            self._pub.put("[" + ",".join(lines) + "]")
        except Exception as exc:  # from a timer or a camera's tap: never an unexpected error
            self.failed += 1
            if self._throttle.allow("put") is not None:
                log.warning("%s: a batch of %d samples was not put (%s; %d batches so far)", self.key, len(lines),
                            exc, self.failed)  # fmt: skip
            return
        self.puts += 1
        self.samples += len(lines)

    def close(self) -> None:
        """What is waiting goes out; then the publisher is undeclared (a closed session: nothing)."""
        if self._closed:
            return
        try:
            self.flush()
        finally:
            self._closed = True
            try:
                self._pub.undeclare()
            except Exception:  # the session closed first: its declarations went with it
                pass
