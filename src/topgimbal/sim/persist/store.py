"""Writing a state file atomically and durably, and `GroupCommit`: replies to changes held until
a write that includes them is on disk."""

from __future__ import annotations

import asyncio
import concurrent.futures
import json
import logging
import os
import re
import tempfile
from collections.abc import Callable, Mapping
from pathlib import Path
from typing import Any, Generic, TypeVar

from ..servers import Throttled
from .load import FORMAT, VERSION

log = logging.getLogger("topgimbal.sim")
T = TypeVar("T")


def dumps(state: Mapping[str, Any]) -> bytes:
    doc = {"format": FORMAT, "version": VERSION, "state": state}
    return json.dumps(doc, indent=1, sort_keys=True, default=str, allow_nan=False).encode("utf-8")


def _temp_pattern(p: Path) -> re.Pattern[str]:
    # tempfile.mkstemp(prefix=".<name>.", suffix=".tmp") names: 8 characters of [a-z0-9_].
    return re.compile(rf"\.{re.escape(p.name)}\.[a-z0-9_]{{8}}\.tmp")


def write_atomic(path: str | Path, data: bytes) -> None:
    """Temporary file, fsync, rename over `path`, fsync of the directory."""
    p = Path(path)
    p.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(prefix=f".{p.name}.", suffix=".tmp", dir=str(p.parent))
    try:
        with os.fdopen(fd, "wb") as f:
            f.write(data)
            f.flush()
            os.fsync(f.fileno())
        os.replace(tmp, p)
    except BaseException:
        try:
            os.unlink(tmp)
        except OSError:
            pass
        raise
    try:
        dfd = os.open(str(p.parent), os.O_RDONLY)
    except OSError:
        return
    try:
        os.fsync(dfd)  # the rename itself is durable only once the directory is
    except OSError:
        pass
    finally:
        os.close(dfd)


def save(path: str | Path, state: Mapping[str, Any]) -> None:
    write_atomic(path, dumps(state))


def remove_stale_temps(path: str | Path) -> list[str]:
    """Delete temporaries of this state file left by a crash (our naming pattern only)."""
    p = Path(path)
    pattern = _temp_pattern(p)
    removed: list[str] = []
    try:
        entries = list(os.scandir(p.parent))
    except OSError:
        return removed
    for entry in entries:
        if pattern.fullmatch(entry.name) and entry.is_file(follow_symlinks=False):
            try:
                os.unlink(entry.path)
                removed.append(entry.name)
            except OSError:
                pass
    return removed


class GroupCommit(Generic[T]):
    """Hold items (replies) until the state they acknowledge is on disk.

    `submit(items, dirty=True)`: the state changed; `items` go out (via `release`) once a write
    that started after this call has completed. `submit(items, dirty=False)`: nothing changed, but
    the items must not overtake items held before them: they go out with the next release. One
    write is in flight at a time; everything submitted meanwhile shares the next one. A failed
    write drops its items (an acknowledgement is never sent for a change that is not on disk),
    logs one line and is retried with the next change. At most `max_held` items wait at once (a
    flood of changes during a slow fsync): beyond that, items are dropped unsent (the change is
    still written, with the next batch; only its acknowledgement is lost, as on a lossy link).
    """

    def __init__(
        self,
        path: Path,
        snapshot: Callable[[], Mapping[str, Any]],
        release: Callable[[list[T]], None],
        drop: Callable[[list[T]], None] | None = None,
        max_held: int = 4096,
    ) -> None:
        self.path = path
        self.max_held = max_held
        self.overflowed = 0
        self._throttled = Throttled()
        self.snapshot = snapshot
        self.release = release
        self.drop = drop or (lambda items: None)
        self.commits = 0
        self.failures = 0
        self._next: list[T] = []
        self._next_dirty = False
        self._inflight: list[T] | None = None
        self._idle = asyncio.Event()
        self._idle.set()
        self._executor: concurrent.futures.ThreadPoolExecutor | None = None

    @property
    def busy(self) -> bool:
        return self._inflight is not None or bool(self._next)

    def submit(self, items: list[T], *, dirty: bool) -> None:
        if not dirty and not self.busy:
            self.release(items)
            return
        self._next_dirty = self._next_dirty or dirty
        if len(self._next) + len(items) + len(self._inflight or ()) > self.max_held:
            self.overflowed += len(items)
            self._throttled.warning(
                "held", f"state file {self.path}: {self.max_held} replies already wait for the disk: replies dropped"
            )
            self.drop(items)
            if self._inflight is None:
                self._start()
            return
        self._next.extend(items)
        if self._inflight is None:
            self._start()

    def _start(self) -> None:
        items, self._next = self._next, []
        if not self._next_dirty:
            self.release(items)  # held only to keep their order: nothing new to write
            return
        self._next_dirty = False
        try:
            data = dumps(self.snapshot())  # on the loop thread: a consistent state
        except (TypeError, ValueError) as exc:  # a value JSON cannot hold: never acknowledge it
            self._finish(items, exc)
            return
        try:
            loop = asyncio.get_running_loop()
        except RuntimeError:  # no event loop (a synchronous caller): write here
            self._finish(items, self._write_now(data))
            return
        if self._executor is None:
            self._executor = concurrent.futures.ThreadPoolExecutor(1, thread_name_prefix="topgimbal-state")
        self._inflight = items
        self._idle.clear()
        fut = loop.run_in_executor(self._executor, write_atomic, self.path, data)
        fut.add_done_callback(self._done)

    def _write_now(self, data: bytes) -> BaseException | None:
        try:
            write_atomic(self.path, data)
        except OSError as exc:
            return exc
        return None

    def _done(self, fut: asyncio.Future[None]) -> None:
        items, self._inflight = self._inflight or [], None
        exc = fut.exception() if not fut.cancelled() else asyncio.CancelledError()
        self._finish(items, exc)
        if self._next:
            self._start()
        if self._inflight is None:
            self._idle.set()

    def _finish(self, items: list[T], exc: BaseException | None) -> None:
        if exc is None:
            self.commits += 1
            self.release(items)
            return
        self.failures += 1
        self._next_dirty = True  # the change is still not on disk: the next write carries it
        log.error("state file %s: write failed (%s): %d replies withheld", self.path, exc, len(items))
        self.drop(items)

    async def drain(self) -> None:
        """Wait until nothing is in flight or held."""
        while self.busy:
            await self._idle.wait()
            if self._next and self._inflight is None:
                self._start()

    def close(self) -> None:
        if self._executor is not None:
            self._executor.shutdown(wait=True)
            self._executor = None
