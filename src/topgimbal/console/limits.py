"""What the console accepts from a page over the WebSocket, and the limits on it.

Every op the page sends is a small JSON object (well under 1 KiB). Anything else is answered
with an error that says what was wrong and what is allowed, and the socket stays open:

- a text message longer than `MAX_MESSAGE_BYTES` (64 KiB); the WebSocket layer itself refuses a
  message above `MAX_FRAME_BYTES` (1 MiB) before buffering it and closes with code 1009;
- JSON nested deeper than `MAX_DEPTH` (32) arrays/objects (checked before parsing, so a
  100k-deep document costs one linear scan, not a RecursionError);
- a number beyond `MAX_NUMBER_ABS` (1e15) in magnitude, `NaN` or `Infinity` (no op needs more,
  and `float()` of a 400-digit integer overflows);
- a binary message, invalid JSON, or JSON that is not an object.

A page may send `MAX_OPS_PER_S` (100) messages a second, in bursts of `OPS_BURST` (50); beyond
that its messages are read later (`OpRate`), so one flooding page cannot starve the others.
"""

from __future__ import annotations

import json
import math
from typing import Any, NoReturn

from ..errors import TopGimbalError

MAX_MESSAGE_BYTES = 64 * 1024
MAX_FRAME_BYTES = 1024 * 1024
MAX_DEPTH = 32
MAX_NUMBER_ABS = 1e15
MAX_OPS_PER_S = 100.0  # per page (a page sends ~10 a second while the pad is dragged)
OPS_BURST = 50.0
_MAX_INT_DIGITS = 16  # 1e15 has 16 digits; longer integer text is refused before it is converted


class MessageError(TopGimbalError, ValueError):
    """A WebSocket message the console does not accept (the text says why and what is allowed)."""


def too_deep(text: str, limit: int = MAX_DEPTH) -> bool:
    """True when JSON `text` nests arrays/objects more than `limit` deep (brackets inside strings
    do not count). One linear scan, stopping at the first level beyond the limit."""
    if text.count("[") + text.count("{") <= limit:
        return False
    depth = 0
    in_string = escaped = False
    for c in text:
        if in_string:
            if escaped:
                escaped = False
            elif c == "\\":
                escaped = True
            elif c == '"':
                in_string = False
        elif c == '"':
            in_string = True
        elif c in "[{":
            depth += 1
            if depth > limit:
                return True
        elif c in "]}":
            depth -= 1
    return False


def _number_error(text: str) -> MessageError:
    shown = text if len(text) <= 24 else f"{text[:12]}…({len(text)} characters)"
    return MessageError(f"the number {shown} is too large: numbers are limited to ±{MAX_NUMBER_ABS:g}")


def _parse_int(text: str) -> int:
    if len(text.lstrip("-")) > _MAX_INT_DIGITS:
        raise _number_error(text)
    value = int(text)
    if abs(value) > MAX_NUMBER_ABS:
        raise _number_error(text)
    return value


def _parse_float(text: str) -> float:
    value = float(text)
    if not math.isfinite(value) or abs(value) > MAX_NUMBER_ABS:
        raise _number_error(text)
    return value


def _parse_constant(name: str) -> NoReturn:
    raise MessageError(f"{name} is not allowed: numbers must be finite and within ±{MAX_NUMBER_ABS:g}")


def _json_kind(value: object) -> str:
    if value is None or isinstance(value, bool):
        return json.dumps(value)
    if isinstance(value, (int, float)):
        return "a number"
    return "a string" if isinstance(value, str) else "an array"


def parse_message(data: str | bytes) -> dict[str, Any]:
    """The op object a text message carries; MessageError for anything outside the limits."""
    if isinstance(data, (bytes, bytearray)):
        raise MessageError(f"binary messages are not accepted ({len(data)} bytes): send ops as JSON text")
    size = len(data.encode("utf-8", "surrogatepass"))
    if size > MAX_MESSAGE_BYTES:
        raise MessageError(
            f"message too long ({size} bytes): ops are JSON objects of at most {MAX_MESSAGE_BYTES} bytes"
        )
    if too_deep(data):
        raise MessageError(f"JSON nested too deeply (more than {MAX_DEPTH} levels of arrays/objects)")
    try:
        msg = json.loads(data, parse_int=_parse_int, parse_float=_parse_float, parse_constant=_parse_constant)
    except MessageError:
        raise
    except (ValueError, RecursionError) as exc:
        raise MessageError(f"not valid JSON: {exc}") from None
    if not isinstance(msg, dict):
        raise MessageError(f'expected a JSON object such as {{"op": "status"}}, got {_json_kind(msg)}')
    return msg


class OpRate:
    """At most `rate_per_s` messages a second from one page, in bursts of up to `burst`.

    A page over its rate is not answered with errors (which would cost the server as much as
    the ops): its next message is simply read later, so TCP pushes back on the page and the
    other pages keep their turn. `delay_s(now)` says how long to wait before reading on."""

    def __init__(self, rate_per_s: float = MAX_OPS_PER_S, burst: float = OPS_BURST) -> None:
        self.rate_per_s = rate_per_s
        self.burst = burst
        self._tokens = burst
        self._last: float | None = None

    def delay_s(self, now: float) -> float:
        """Take one message; the wait (0 when within the rate) before handling it."""
        if self._last is not None:
            self._tokens = min(self.burst, self._tokens + (now - self._last) * self.rate_per_s)
        self._last = now
        self._tokens -= 1.0
        return 0.0 if self._tokens >= 0 else -self._tokens / self.rate_per_s


__all__ = [
    "MAX_DEPTH",
    "MAX_FRAME_BYTES",
    "MAX_MESSAGE_BYTES",
    "MAX_NUMBER_ABS",
    "MAX_OPS_PER_S",
    "MessageError",
    "OpRate",
    "parse_message",
]
