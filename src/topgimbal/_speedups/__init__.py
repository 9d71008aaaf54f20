"""The optional C fast path (libtopgimbal's scanner and codecs, compiled at install time).

A leaf below `protocol/`: it imports nothing from topgimbal; the protocol layer hands it its own
classes (`Frame`, `Diagnostic`, `Message`) and dialects. Everything here falls back to None when
the extension is not built (no compiler at install), stale, or disabled with `TOPGIMBAL_PURE=1`;
callers then keep the pure Python path. Both paths give identical results (tests/speedups/).

    make_scan(Frame, Diagnostic)            -> a drop-in for FrameParser._scan, or None
    make_decoder(dialect, Message, pure)    -> a drop-in for Dialect.decode, or None
"""

from __future__ import annotations

import os
from collections.abc import Callable
from typing import Any

from .spec import decoder_tables

ABI_VERSION = 1  # must match _ctop.c
SCAN_STRICT_IDENT = 0x01
SCAN_OVERLAP_GUARD = 0x02
SCAN_DEFAULT = SCAN_STRICT_IDENT | SCAN_OVERLAP_GUARD

# FrameParser's diagnostic texts by scanner reason (enum tg_reason in c/include/topgimbal.h).
# They must read exactly as protocol/parser.py words them; tests/speedups compare the two paths.
REASONS = {
    1: "bytes outside a frame",
    2: "'#' not followed by a valid header/address/length",
    4: "incomplete frame followed by a good one",
    5: "incomplete frame at end of stream",
    6: "checksum matched by chance: overlaps the next frame",
}
_OVERSIZE = 3

_ext: Any = None
_status = ""
if os.environ.get("TOPGIMBAL_PURE", "") not in ("", "0"):
    _status = "disabled by TOPGIMBAL_PURE"
else:
    try:
        from . import _ctop as _loaded  # type: ignore[attr-defined]
    except ImportError as exc:
        _status = f"not built ({exc})"
    else:
        if getattr(_loaded, "ABI_VERSION", None) != ABI_VERSION:
            _status = "stale build (rebuild: pip install -e .)"
        else:
            _ext = _loaded
            _status = "enabled"


def enabled() -> bool:
    """True when the C fast path is in use (built, current, and not disabled by TOPGIMBAL_PURE)."""
    return _ext is not None


def status() -> str:
    """Why the fast path is or is not in use, in words."""
    return _status


def scan_flags(parser_cls: Any) -> int:
    """Which optional scanner rules a FrameParser class follows (probed on crafted input), so the
    fast scan can match a parser written before or after those rules."""
    flags = 0

    def frame(header: bytes, ident: bytes, data: bytes, rw: bytes = b"w", addr: bytes = b"UG") -> bytes:
        length = b"%X" % len(data) if header in (b"#TP", b"#tp") else bytes([len(data)])
        body = header + addr + length + rw + ident + data
        return body + b"%02X" % (sum(body) & 0xFF)

    if not any(type(e).__name__ == "Frame" for e in parser_cls().feed_datagram(frame(b"#TP", b"G!C", b"00"))):
        flags |= SCAN_STRICT_IDENT
    # A frame whose checksum matches by chance, swallowing the start of a real frame that runs past
    # it: the outer frame's checksum characters are the real frame's first data characters.
    inner = frame(b"#tP", b"GAC", b"3A" + b"0" * 14, addr=b"GU")
    need = (0x3A - sum(b"#tpUGFwABCX" + inner[:10])) % 256
    total = need if need >= 4 * 0x30 else need + 256
    pad = b""
    for k in range(4):
        c = min(0x7E, total - 0x30 * (3 - k))
        pad += bytes([c])
        total -= c
    events = parser_cls().feed_datagram(b"#tpUGFwABCX" + pad + inner)
    if any(type(e).__name__ == "Frame" and e.ident == "GAC" for e in events):
        flags |= SCAN_OVERLAP_GUARD
    return flags


def make_scan(frame_cls: type, diagnostic_cls: type, flags: int = SCAN_DEFAULT) -> Callable[..., int] | None:
    """A FrameParser._scan replacement `(self, buf, pos, out, final) -> pos`, or None.

    Good frames are built in C; the rare events go through the parser's own `_discard` and
    `_emit_recovered`, so diagnostics and statistics are the pure parser's."""
    if _ext is None:
        return None
    c_scan = _ext.scan

    def _scan(self: Any, buf: bytes, pos: int, out: list[Any], final: bool) -> int:
        pos, items, nframes = c_scan(buf, pos, final, self.max_data_length, self.recover_length, flags, frame_cls)
        stats = self.stats
        if nframes == len(items):
            out += items
            stats.frames += nframes
            return pos  # type: ignore[no-any-return]
        for item in items:
            if type(item) is not tuple:
                out.append(item)
                stats.frames += 1
            elif item[0] == "D":
                _, start, end, kind, reason = item
                if reason == _OVERSIZE:
                    stats.oversize += 1
                    why = f"declared length above the {self.max_data_length}-byte bound"
                else:
                    why = REASONS[reason]
                self._discard(buf[start:end], out, why, kind)
            elif item[0] == "C":
                _, start, end, nxt = item
                stats.bad_checksums += 1
                stats.bytes_discarded += nxt - start
                stats.resyncs += 1
                crc = buf[end - 2 : end].decode("latin-1")
                expected = "%02X" % (sum(buf[start : end - 2]) & 0xFF)
                out.append(diagnostic_cls("bad_checksum", f"checksum {crc!r}, expected {expected!r}", buf[start:end]))
            else:  # "R": a frame with a wrong length character, recovered
                _, start, end, frame = item
                self._emit_recovered((frame, end), buf, start, out)
        return pos  # type: ignore[no-any-return]

    return _scan


def make_decoder(dialect: Any, message_cls: type, pure: Callable[[Any], Any]) -> Any:
    """A Dialect.decode replacement for `dialect` (callable frame -> Message, with
    `.decode_many(frames)`), or None. `pure` is the pure decoder it hands frames to whenever the C
    core is not sure, and whose words every error keeps."""
    if _ext is None:
        return None
    return _ext.Decoder(decoder_tables(dialect.commands.values()), message_cls, pure)
