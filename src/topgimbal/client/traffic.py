"""Traffic log (JSONL) and replay.

One line per frame: `{"t": wall-clock seconds, "mono": monotonic seconds, "dir": "in" | "out",
"raw": frame text (latin-1, non-ASCII bytes as \\u00NN), "decoded": Message.to_dict() or null}`.
The first line is a header: `{"topgimbal_log": 1, "url": ..., "model": ..., "dialect": ...}`.
Replay re-sends the "out" frames with their original spacing (python-can's MessageSync)."""

from __future__ import annotations

import json
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import IO

from ..clock import monotonic, wall_time
from ..protocol import Frame, Message, parse_frame


@dataclass(frozen=True)
class LogRecord:
    t: float
    mono: float
    direction: str
    frame: Frame
    decoded: dict[str, object] | None


class TrafficLog:
    """Append-only JSONL writer. Line-buffered so a crash loses at most the last line."""

    def __init__(self, path: str | Path, *, url: str = "", model: str = "", dialect: str = "") -> None:
        self.path = Path(path)
        self._fh: IO[str] | None = self.path.open("a", encoding="utf-8", buffering=1)
        self._write({"topgimbal_log": 1, "url": url, "model": model, "dialect": dialect, "t": wall_time()})

    def _write(self, obj: dict[str, object]) -> None:
        if self._fh is not None:
            self._fh.write(json.dumps(obj, ensure_ascii=True) + "\n")

    def record(self, direction: str, frame: Frame, message: Message | None) -> None:
        self._write(
            {
                "t": round(wall_time(), 6),
                "mono": round(monotonic(), 6),
                "dir": direction,
                "raw": frame.to_bytes().decode("latin-1"),
                "decoded": message.to_dict() if message is not None else None,
            }
        )

    def close(self) -> None:
        if self._fh is not None:
            self._fh.close()
            self._fh = None


def read_log(path: str | Path) -> Iterator[LogRecord]:
    """The frames of a traffic log, in order (header and unreadable lines skipped)."""
    with Path(path).open(encoding="utf-8") as fh:
        for line in fh:
            line = line.strip()
            if not line:
                continue
            try:
                obj = json.loads(line)
                if "dir" not in obj:
                    continue
                frame = parse_frame(obj["raw"].encode("latin-1"))
            except (ValueError, KeyError, RecursionError):
                continue  # not JSON, no frame, or nested past Python's recursion
            # JSON of another shape (a number, a list, a non-text "raw") raises TypeError or
            # AttributeError to the caller: `replay` names the file as not a traffic log
            yield LogRecord(
                float(obj.get("t", 0.0)), float(obj.get("mono", 0.0)), obj["dir"], frame, obj.get("decoded")
            )
