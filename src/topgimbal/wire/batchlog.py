"""The client's JSONL traffic log, written in batches (the proxy's `--log`).

`client.traffic.TrafficLog` writes each line as it comes (line-buffered: one system call per
frame, so a crash loses at most a line). On the proxy's busy path that costs a system call per
frame crossing; `BatchedTrafficLog` keeps the same format and lines but hands them to the file
in one write per `flush()` (the proxy flushes on a short timer, at `MAX_LINES` waiting lines, and
at stop, which Ctrl-C and SIGTERM reach). What a hard kill loses is at most one timer period.
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

from ..client.traffic import TrafficLog

MAX_LINES = 512  # lines waiting before they are written without waiting for the timer


class BatchedTrafficLog(TrafficLog):
    """TrafficLog whose lines wait in memory until `flush()` (or `MAX_LINES` of them wait)."""

    def __init__(self, path: str | Path, *, url: str = "", model: str = "", dialect: str = "") -> None:
        self._lines: list[str] = []
        super().__init__(path, url=url, model=model, dialect=dialect)
        self.flush()  # the header line at once: the file says what it is from the start

    def _write(self, obj: dict[str, Any]) -> None:
        # TrafficLog's line, serialised the same way, kept for the next flush
        self._lines.append(json.dumps(obj, ensure_ascii=True))
        if len(self._lines) >= MAX_LINES:
            self.flush()

    @property
    def waiting(self) -> int:
        """Lines not yet handed to the file."""
        return len(self._lines)

    def flush(self) -> None:
        """Write every waiting line in one call."""
        if self._lines and self._fh is not None:
            self._lines.append("")
            text = "\n".join(self._lines)
            self._lines.clear()
            self._fh.write(text)

    def close(self) -> None:
        self.flush()
        super().close()
