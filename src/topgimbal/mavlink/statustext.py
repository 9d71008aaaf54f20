"""STATUSTEXT longer than 50 bytes, as MAVLink 2 chunks: every chunk carries the same nonzero `id`
and its `chunk_seq` (0, 1, ...); a chunk shorter than 50 bytes (a NUL in the field) ends the text,
so a text that fills its last chunk exactly is followed by an empty one. A text that fits one chunk
goes with id 0 ("the only chunk"), as before. Ground stations that do not reassemble (MAVProxy,
older QGC) show the chunks in order, the first one still saying what failed: the callers put the
command first.

Bounded: at most MAX_CHUNKS chunks (200 bytes); a longer text is cut, with "..." at its end. Text
is split between UTF-8 characters, never inside one."""

from __future__ import annotations

import itertools
from typing import TYPE_CHECKING

from ..links.mav import mavlink

if TYPE_CHECKING:
    from .node import Component

CHUNK_BYTES = 50
MAX_CHUNKS = 4
_ids = itertools.cycle(range(1, 65536))  # 0 means "not chunked"


def chunks(text: str) -> list[bytes]:
    """The text as STATUSTEXT fields: one of at most 50 bytes, or MAX_CHUNKS at most."""
    data = text.encode("utf-8", "replace")
    limit = CHUNK_BYTES * MAX_CHUNKS
    if len(data) > limit:
        data = _cut(data, limit - 3) + b"..."
    out: list[bytes] = []
    while data:
        piece = _cut(data, CHUNK_BYTES)
        out.append(piece)
        data = data[len(piece) :]
    if not out:
        return [b""]
    if len(out) > 1 and len(out[-1]) == CHUNK_BYTES and len(out) < MAX_CHUNKS:
        out.append(b"")  # the end, where the last chunk left no room for a NUL
    return out


def _cut(data: bytes, n: int) -> bytes:
    """The longest prefix of at most n bytes that ends between UTF-8 characters."""
    if len(data) <= n:
        return data
    end = n
    while end > 0 and (data[end] & 0xC0) == 0x80:  # a continuation byte: step back to a character's start
        end -= 1
    return data[:end] if end > 0 else data[:n]


def send_statustext(comp: Component, text: str, severity: int = 6) -> int:
    """Send `text` from `comp` (severity: 3 error, 4 warning, 6 info); the number of chunks sent."""
    parts = chunks(text)
    ml = mavlink()
    if len(parts) == 1:
        comp.send(ml.MAVLink_statustext_message(severity, parts[0], 0, 0))
        return 1
    ident = next(_ids)
    for seq, part in enumerate(parts):
        comp.send(ml.MAVLink_statustext_message(severity, part, ident, seq))
    return len(parts)
