"""Loading a state file: refused unless it is a regular file of sane size, nesting, JSON, numbers,
and keys and types the device's own snapshot has."""

from __future__ import annotations

import json
import math
import os
import re
import stat
from collections.abc import Mapping
from datetime import datetime
from pathlib import Path
from typing import Any

from ...errors import TopGimbalError

FORMAT = "topgimbal-sim-state"
VERSION = 1
MAX_BYTES = 1 << 20  # our files are ~3 KB; anything near this is not one of them
MAX_NESTING = 64  # ours nest 4 deep; deeper files are refused before the JSON parser recurses
MAX_INT = 1 << 63
MAX_TEXT = 4096


class StateFileError(TopGimbalError, ValueError):
    """The state file cannot be used; the message names the file, the key and what is wrong."""


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
