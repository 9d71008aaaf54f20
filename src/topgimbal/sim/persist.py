"""Persistent settings on disk: checked on load, durable before acknowledged, atomic on write.

Writing: the JSON goes to a temporary file `.<name>.XXXXXXXX.tmp` in the same directory, is
flushed and fsynced, renamed over the old file (atomic on POSIX), and the directory is fsynced. A
kill -9 at any point leaves the old file or the new one, never a torn mix; a temporary left by a
crash is removed at the next start (`remove_stale_temps`).

Durability of acknowledgements (`GroupCommit`): the reply to a state-changing request is held until
a write that includes the change has reached the disk. Changes arriving while a write is in flight
share the next one (group commit), so a host writing at 100 Hz costs one fsync per batch, not one
per request.

Loading: a file that is not a regular file (FIFO, device, directory) is refused before it is
opened (and opened non-blocking, so a file swapped for a FIFO cannot hang the start); then its
size, nesting, JSON syntax, numbers (no NaN, Infinity, 1e400, 400-digit integers), and every key
and type against the device's own snapshot are checked, each failure as one line naming the file
and the key.
"""

from __future__ import annotations

import asyncio
import concurrent.futures
import json
import logging
import math
import os
import re
import stat
import tempfile
from collections.abc import Callable, Mapping
from datetime import datetime
from pathlib import Path
from typing import Any, Generic, TypeVar

from ..errors import TopGimbalError
from .servers import Throttled

FORMAT = "topgimbal-sim-state"
VERSION = 1
MAX_BYTES = 1 << 20  # our files are ~3 KB; anything near this is not one of them
MAX_NESTING = 64  # ours nest 4 deep; deeper files are refused before the JSON parser recurses
MAX_INT = 1 << 63
MAX_TEXT = 4096

log = logging.getLogger("topgimbal.sim")
T = TypeVar("T")


class StateFileError(TopGimbalError, ValueError):
    """The state file cannot be used; the message names the file, the key and what is wrong."""


# -- reading ---------------------------------------------------------------------------------------


def load(path: str | Path, template: Mapping[str, Any] | None = None) -> dict[str, Any] | None:
    """The saved state, or None when the file does not exist yet. With `template` (a fresh
    device's snapshot) every key and type is checked against it."""
    p = Path(path)
    text = _read(p)
    if text is None:
        return None
    data = _parse(p, text)
    if not isinstance(data, dict) or data.get("format") != FORMAT:
        raise StateFileError(f"state file {p} is not a topgimbal simulator state file (format {FORMAT!r})")
    for key in data:
        if key not in ("format", "version", "state"):
            raise StateFileError(f"state file {p}: unknown key {key!r}; known: format, state, version")
    if data.get("version") != VERSION:
        raise StateFileError(f"state file {p} has version {data.get('version')!r}; this simulator reads {VERSION}")
    state = data.get("state")
    if not isinstance(state, dict):
        raise StateFileError(f"state file {p}: 'state' must be an object, got {_kind(state)}")
    if template is not None:
        validate(p, state, template)
    return state


def _read(p: Path) -> str | None:
    try:
        st = os.stat(p)
    except FileNotFoundError:
        return None
    except OSError as exc:
        raise StateFileError(f"state file {p}: {exc.strerror or exc}") from None
    if not stat.S_ISREG(st.st_mode):
        raise StateFileError(f"state file {p} is {_file_kind(st.st_mode)}, not a regular file; give a file path")
    if st.st_size > MAX_BYTES:
        raise StateFileError(f"state file {p} has {st.st_size} bytes; a state file has at most {MAX_BYTES}")
    try:
        # Non-blocking: if the path became a FIFO since the stat, the open cannot hang.
        fd = os.open(p, os.O_RDONLY | os.O_NONBLOCK | os.O_NOCTTY | getattr(os, "O_CLOEXEC", 0))
    except OSError as exc:
        raise StateFileError(f"state file {p}: {exc.strerror or exc}") from None
    try:
        st = os.fstat(fd)
        if not stat.S_ISREG(st.st_mode):
            raise StateFileError(f"state file {p} is {_file_kind(st.st_mode)}, not a regular file; give a file path")
        chunks, size = [], 0
        while size <= MAX_BYTES:
            chunk = os.read(fd, 65536)
            if not chunk:
                break
            chunks.append(chunk)
            size += len(chunk)
    except OSError as exc:
        raise StateFileError(f"state file {p}: {exc.strerror or exc}") from None
    finally:
        os.close(fd)
    if size > MAX_BYTES:
        raise StateFileError(f"state file {p} has more than {MAX_BYTES} bytes; a state file has at most {MAX_BYTES}")
    try:
        return b"".join(chunks).decode("utf-8")
    except UnicodeDecodeError as exc:
        raise StateFileError(
            f"state file {p} is not UTF-8 text (byte {exc.start}); move it away to start fresh"
        ) from None


def _file_kind(mode: int) -> str:
    for test, name in (
        (stat.S_ISDIR, "a directory"),
        (stat.S_ISFIFO, "a FIFO"),
        (stat.S_ISCHR, "a character device"),
        (stat.S_ISBLK, "a block device"),
        (stat.S_ISSOCK, "a socket"),
    ):
        if test(mode):
            return name
    return "not a regular file"


class _BadNumber:
    """A number JSON allows but a state file does not (NaN, Infinity, 1e400, huge integers);
    kept as a value so the check can name the key it sits under."""

    def __init__(self, text: str, what: str = "not a finite number") -> None:
        self.text = text
        self.what = what


def _parse_float(text: str) -> float | _BadNumber:
    value = float(text)
    return value if math.isfinite(value) else _BadNumber(text)


def _parse_int(text: str) -> int | _BadNumber:
    digits = len(text.lstrip("-"))
    if digits <= 30:
        return int(text)
    return _BadNumber(text[:24] + "...", f"an integer of {digits} digits")


_TOKEN = re.compile(r'"(?:[^"\\]|\\.)*"|[\[\]{}]', re.S)


def _parse(p: Path, text: str) -> object:
    depth = 0
    for m in _TOKEN.finditer(text):
        c = m.group()
        if c in "[{":
            depth += 1
            if depth > MAX_NESTING:
                line = text.count("\n", 0, m.start()) + 1
                raise StateFileError(
                    f"state file {p} nests more than {MAX_NESTING} levels deep (line {line}); "
                    "a state file nests 4 levels; move it away to start fresh"
                )
        elif c in "]}":
            depth -= 1
    try:
        return json.loads(text, parse_float=_parse_float, parse_int=_parse_int, parse_constant=_BadNumber)
    except json.JSONDecodeError as exc:
        raise StateFileError(
            f"state file {p} is not valid JSON ({exc.msg} at line {exc.lineno} column {exc.colno}); "
            "move it away to start fresh"
        ) from None
    except (ValueError, RecursionError) as exc:
        raise StateFileError(f"state file {p} is not valid JSON ({exc}); move it away to start fresh") from None


def _kind(value: object) -> str:
    if isinstance(value, _BadNumber):
        return f"{value.text} ({value.what})"
    if value is None:
        return "null"
    if isinstance(value, bool):
        return "true" if value else "false"
    name = {dict: "an object", list: "a list", str: "text", int: "an integer", float: "a number"}.get(type(value))
    return name or type(value).__name__


def validate(p: Path, state: Mapping[str, Any], template: Mapping[str, Any]) -> None:
    """Check `state` against a fresh device's snapshot: the same keys (some may be missing), the
    same types, finite numbers. Raises StateFileError naming the first bad key."""
    model = state.get("model")
    if isinstance(model, str) and model != template.get("model"):
        raise StateFileError(
            f"state file {p} belongs to a {model} simulator, this one is a {template.get('model')}; "
            "give each model its own state file"
        )
    _check(p, state, template, "")


# What a leaf of the snapshot may hold, by the type of the fresh device's value (None: a setting
# that starts unset). bool before int: a bool is an int to isinstance.
_LEAVES: list[tuple[type | None, tuple[type, ...], str]] = [
    (None, (str, int, float, type(None)), "text, a number or null"),
    (bool, (bool,), "true or false"),
    (int, (int,), "an integer"),
    (float, (int, float), "a number"),
    (str, (str,), "text"),
]


def _check(p: Path, value: object, template: object, path: str) -> None:
    def bad(expected: str) -> StateFileError:
        return StateFileError(f"state file {p}: {path or 'state'} is {_kind(value)}; expected {expected}")

    if isinstance(template, dict):
        if not isinstance(value, dict):
            raise bad("an object")
        for key, sub in value.items():
            where = f"{path}.{key}" if path else key
            if key not in template:
                known = sorted(template)
                listed = ", ".join(known[:12]) + (", ..." if len(known) > 12 else "")
                raise StateFileError(f"state file {p}: unknown key {where!r}; known here: {listed}")
            _check(p, sub, template[key], where)
        return
    if isinstance(value, _BadNumber):
        raise bad("a finite number of sensible size (no NaN, Infinity, 1e400 or huge integers)")
    for kind, accepted, expected in _LEAVES:
        if template is None if kind is None else isinstance(template, kind):
            # bool is an int to Python, not to a state file
            if not isinstance(value, accepted) or (isinstance(value, bool) and kind is not bool):
                raise bad(expected)
            break
    if isinstance(value, int) and not -MAX_INT <= value < MAX_INT:
        raise bad("an integer within +-2**63")
    if isinstance(value, str) and len(value) > MAX_TEXT:
        raise bad(f"text of at most {MAX_TEXT} characters")
    if isinstance(template, str) and _is_time(template) and not _is_time(value):
        raise StateFileError(
            f"state file {p}: {path} is {value!r}; expected a time as ISO 8601 text (YYYY-MM-DDTHH:MM:SS)"
        )


def _is_time(value: object) -> bool:
    """A stored time (TIM) as the snapshot writes it: ISO 8601 text."""
    if not isinstance(value, str) or not _ISO_TIME.fullmatch(value):
        return False
    try:
        datetime.fromisoformat(value)
    except ValueError:
        return False
    return True


_ISO_TIME = re.compile(r"\d{4}-\d\d-\d\dT\d\d:\d\d:\d\d(\.\d+)?")


# -- writing ---------------------------------------------------------------------------------------


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
