"""Warnings a remote end can trigger again and again (a flood of new clients, datagrams, failed
sends): each kind is logged at most once per interval, and the next line says how many were left
out. A leaf every layer may use (like errors.py): the simulator's servers and state store, the
proxy, the MAVLink bridge (commands, parameters, endpoints, pointing, camera definitions), the
media server, the RTSP streams and the Zenoh fleet server.

`warning(kind, fmt, *args)` writes the line itself and appends how many were left out; a caller
whose line already counts what it refused (`%d in all`) asks `allow(kind)` and keeps its words."""

from __future__ import annotations

import logging
from collections.abc import Callable

from .clock import monotonic

MAX_KINDS = 64  # kinds remembered; kinds are names in code, so this is never reached in practice


class ThrottledLog:
    """`warning(kind, fmt, *args)`: at most one line per `kind` per `every_s` seconds."""

    def __init__(
        self,
        logger: logging.Logger,
        every_s: float = 10.0,
        clock: Callable[[], float] = monotonic,
        *,
        suffix: str = " ({} more like it not logged)",
    ) -> None:
        self.logger = logger
        self.every_s = every_s
        self.clock = clock
        self.suffix = suffix
        self._last: dict[str, float] = {}  # bounded: MAX_KINDS
        self._left_out: dict[str, int] = {}

    def allow(self, kind: str) -> int | None:
        """Whether a line of `kind` may be logged now: None when not (it is counted), else how many
        were left out since the last one (0 or more); the caller then logs it, in its own words."""
        now = self.clock()
        last = self._last.get(kind)
        if last is not None and now - last < self.every_s:
            self._left_out[kind] = self._left_out.get(kind, 0) + 1
            return None
        if last is None and len(self._last) >= MAX_KINDS:
            oldest = next(iter(self._last))  # forget the oldest kind, and its count
            del self._last[oldest]
            self._left_out.pop(oldest, None)
        self._last[kind] = now
        return self._left_out.pop(kind, 0)

    def warning(self, kind: str, fmt: str, *args: object) -> bool:
        """Log now, or count it for the next line of its kind; True when it was logged."""
        left_out = self.allow(kind)
        if left_out is None:
            return False
        if left_out:
            fmt += self.suffix.format(left_out)
        self.logger.warning(fmt, *args)
        return True
