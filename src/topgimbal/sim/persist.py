"""Persistent settings on disk, written atomically.

A write goes to a temporary file in the same directory, is flushed and fsynced, then renamed over
the old file (rename is atomic on POSIX), and the directory is fsynced. A kill -9 at any point
leaves either the old file or the new one, never a torn mix.
"""

from __future__ import annotations

import json
import os
import tempfile
from pathlib import Path
from typing import Any

FORMAT = "topgimbal-sim-state"
VERSION = 1


class StateFileError(ValueError):
    pass


def load(path: str | Path) -> dict[str, Any] | None:
    """The saved state, or None when the file does not exist yet."""
    p = Path(path)
    try:
        text = p.read_text(encoding="utf-8")
    except FileNotFoundError:
        return None
    except OSError as exc:
        raise StateFileError(f"state file {p}: {exc.strerror or exc}") from None
    try:
        data = json.loads(text)
    except json.JSONDecodeError as exc:
        raise StateFileError(f"state file {p} is not valid JSON ({exc}); move it away to start fresh") from None
    if not isinstance(data, dict) or data.get("format") != FORMAT:
        raise StateFileError(f"state file {p} is not a topgimbal simulator state file (format {FORMAT!r})")
    if data.get("version") != VERSION:
        raise StateFileError(f"state file {p} has version {data.get('version')!r}; this simulator reads {VERSION}")
    state = data.get("state")
    if not isinstance(state, dict):
        raise StateFileError(f"state file {p} has no 'state' object")
    return state


def save(path: str | Path, state: dict[str, Any]) -> None:
    p = Path(path)
    p.parent.mkdir(parents=True, exist_ok=True)
    text = json.dumps({"format": FORMAT, "version": VERSION, "state": state}, indent=1, sort_keys=True, default=str)
    fd, tmp = tempfile.mkstemp(prefix=f".{p.name}.", suffix=".tmp", dir=str(p.parent))
    try:
        with os.fdopen(fd, "w", encoding="utf-8") as f:
            f.write(text)
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
        os.fsync(dfd)
    except OSError:
        pass
    finally:
        os.close(dfd)
