"""Reading a file the user named (a target list, a log, a camera list): regular files only, read
up to a bound, JSON nested at most MAX_JSON_NESTING deep.

`stat()` says nothing true about a special file: /dev/zero has size 0 and reads for ever, a FIFO
blocks the open until a writer comes. So the file is opened non-blocking, must be a regular file
by `fstat()` of what was opened, and is read up to `max_bytes + 1` bytes whatever its size says.
Python's JSON parser recurses once per level: 100,000 `[` end in a RecursionError, so the nesting
is counted first (strings skipped) and refused past the bound."""

from __future__ import annotations

import json
import os
import re
import stat
from pathlib import Path
from typing import Any

MAX_JSON_NESTING = 64  # what a user's file needs (a target list nests 3 levels), far below Python's limit

_TOKEN = re.compile(r'"(?:[^"\\]|\\.)*"|[\[\]{}]', re.S)


class InputFileError(ValueError):
    """A file that cannot be read as asked: not a regular file, too large, not text, too deep."""


def read_bytes(path: str | Path, max_bytes: int, what: str) -> bytes:
    """The bytes of the regular file `path`, at most `max_bytes` (InputFileError otherwise)."""
    try:
        fd = os.open(path, os.O_RDONLY | os.O_NONBLOCK | getattr(os, "O_NOCTTY", 0))
    except IsADirectoryError:
        raise InputFileError(f"{what} {path}: a folder, not a file") from None
    except OSError as exc:
        raise InputFileError(f"{what} {path}: {exc.strerror or exc}") from None
    with os.fdopen(fd, "rb") as fh:
        if not stat.S_ISREG(os.fstat(fh.fileno()).st_mode):
            raise InputFileError(f"{what} {path}: not a regular file (a FIFO, a device or a socket): give a file")
        data = fh.read(max_bytes + 1)
    if len(data) > max_bytes:
        raise InputFileError(f"{what} {path}: larger than {max_bytes} bytes")
    return data


def require_regular(path: str | Path, what: str) -> None:
    """InputFileError unless `path` is a regular file (for a file read in full however large it is,
    a log: /dev/zero would be read for ever, a FIFO would block the open)."""
    try:
        mode = os.stat(path).st_mode
    except OSError as exc:
        raise InputFileError(f"{what} {path}: {exc.strerror or exc}") from None
    if not stat.S_ISREG(mode):
        raise InputFileError(f"{what} {path}: not a regular file (a FIFO, a device or a folder): give a file")


def read_text(path: str | Path, max_bytes: int, what: str) -> str:
    try:
        return read_bytes(path, max_bytes, what).decode("utf-8")
    except UnicodeDecodeError as exc:
        raise InputFileError(f"{what} {path}: not UTF-8 text ({exc.reason} at byte {exc.start})") from None


def check_nesting(text: str, what: str, limit: int = MAX_JSON_NESTING) -> None:
    """InputFileError when `text`'s brackets nest deeper than `limit` (strings not counted)."""
    depth = 0
    for m in _TOKEN.finditer(text):
        c = m.group()
        if c in "[{":
            depth += 1
            if depth > limit:
                line = text.count("\n", 0, m.start()) + 1
                raise InputFileError(f"{what}: JSON nested more than {limit} levels deep (line {line})")
        elif c in "]}":
            depth -= 1


def loads(text: str, what: str) -> Any:
    """JSON from `text`, its nesting bounded first (InputFileError, never a RecursionError)."""
    check_nesting(text, what)
    try:
        return json.loads(text)
    except (ValueError, RecursionError) as exc:  # JSONDecodeError is a ValueError
        raise InputFileError(f"{what}: not JSON ({exc})") from None


def load_json(path: str | Path, max_bytes: int, what: str) -> Any:
    return loads(read_text(path, max_bytes, what), f"{what} {path}")
