"""Streaming frame parser: bytes in any chunking -> frames and diagnostics.

Contract: `feed()` never raises, never waits on bytes that cannot come (a good frame already in the
buffer is never held back by garbage before it), keeps at most two maximum-size frames buffered,
resynchronises at the next `#`, and drops only the frame whose checksum is wrong.

No valid frame is lost after garbage: an identifier is three ASCII letters or digits, and a
candidate whose checksum is right yields to a valid frame that starts inside it (it matched by
chance: garbage that happened to check out would otherwise swallow the real frame after it). The
price, on a byte stream only: a frame whose own data hold the start of what could be a frame
running past its end (a '#' and a plausible header: possible only in binary payloads, since ASCII
data never contain '#') is delivered when the next bytes decide it, not before. A datagram's end
decides at once.

Length recovery: when an ASCII-header frame fails its checksum at its declared length, the parser
takes the length that ends exactly where the next thing starts (the next `#`, CR, LF, or the end of
a datagram given to `feed_datagram()`); if that frame's checksum is right it is accepted and
reported as a `length_mismatch` diagnostic (real C12: `#tpDU3rVER0105025A`). On a byte stream a
recovered frame is therefore delivered when the next frame or line end arrives.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any
from zlib import adler32 as _adler32

from .. import _speedups
from .diagnostics import (
    BAD_CHECKSUM,
    BAD_HEADER,
    END_OF_STREAM,
    INCOMPLETE_FOLLOWED,
    INNER_FRAME,
    OUTSIDE,
    OVERSIZE,
    RECOVERED,
    WHY,
    Diagnostic,
    ParserStats,
)
from .frame import Frame, checksum_text
from .scanning import (
    ADDR,
    ASCII_HDR,
    HDR,
    HEADERS,
    HEX2,
    HEX2_LOWER,
    HEXVAL,
    RW,
    SEPARATORS,
    bad_prefix,
    recover,
    remember_header,
)

_new_tuple = tuple.__new__


@dataclass
class FrameParser:
    """Incremental parser. `max_data_length` bounds what the extended headers may claim."""

    max_data_length: int = 1024
    recover_length: bool = True
    stats: ParserStats = field(default_factory=ParserStats)
    _buf: bytes = b""

    def reset(self) -> None:
        self._buf = b""

    @property
    def buffered(self) -> int:
        return len(self._buf)

    def feed(self, data: bytes) -> list[Frame | Diagnostic]:
        """Add bytes; return the frames (and diagnostics) they complete, in wire order."""
        return self._feed_py(data, False, None)

    def feed_datagram(self, data: bytes) -> list[Frame | Diagnostic]:
        """Feed one whole datagram (UDP): its end is a frame boundary, so nothing is kept for the
        next one and a frame with a wrong length character that ends the datagram is recovered."""
        return self._feed_py(data, True, None)

    def flush(self) -> list[Frame | Diagnostic]:
        """Resolve whatever is buffered as if the stream ended here (end of a datagram or file)."""
        return self._feed_py(b"", True, None)

    def feed_messages(self, data: bytes, decode: Callable[[Frame], Any], *, final: bool = False) -> list[Any]:
        """`feed` (or `feed_datagram` when `final`) with every frame replaced by `decode(frame)`, in
        one pass: `parser.feed_messages(datagram, dialect.decode, final=True)` gives the Messages
        and Diagnostics of a datagram in wire order. With the C fast path and a decoder of the
        catalog (`Dialect.decode`, `any_decoder()`), bytes to Messages is a single C call."""
        return self._feed_py(data, final, decode)

    # -- internals -------------------------------------------------------------------------

    def _feed_py(self, data: bytes, final: bool, decode: Callable[[Frame], Any] | None) -> list[Any]:
        """feed / feed_datagram / flush / feed_messages in pure Python. With the fast path in use,
        those four methods are the C scanner's, which give the same events and statistics."""
        stats = self.stats
        if final and not self._buf and type(data) is bytes:
            # The commonest datagram is exactly one good frame (every UDP reply and report): judged
            # here in a few C calls, with the same result and statistics as the loop below.
            head = HEADERS.get(data[:10])
            n = len(data)
            if head is not None and n == 12 + head[0] and n <= 258 and head[0] <= self.max_data_length:
                s = ((_adler32(data[:-2]) & 0xFFFF) - 1) & 0xFF
                crc = data[-2:]
                if (crc == HEX2[s] or crc == HEX2_LOWER[s]) and data.find(b"#", 1) < 0:
                    stats.bytes += n
                    stats.frames += 1
                    frame = _new_tuple(Frame, head[1] + (data[10:-2], None))
                    return [frame if decode is None else decode(frame)]
        stats.bytes += len(data)
        buf = self._buf + data if self._buf else bytes(data)
        n_buf = len(buf)
        out: list[Any] = []
        append = out.append
        max_data = self.max_data_length
        # The common case inline: good frames back to back (line ends between them are no news),
        # each with a header seen before. Anything else goes to the full scan from where it is.
        pos = 0
        while pos < n_buf:
            if buf[pos] != 0x23:
                # line ends are skipped only before a '#' or the end (else they belong to the bytes
                # the full scan discards, and its diagnostic shows them)
                after = pos + 1
                while after < n_buf and buf[after] in SEPARATORS:
                    after += 1
                if buf[pos] in SEPARATORS and (after == n_buf or buf[after] == 0x23):
                    pos = after
                    continue
                break
            head = HEADERS.get(buf[pos : pos + 10])
            if head is None or head[0] > max_data:
                break
            end = pos + 12 + head[0]
            if end > n_buf:
                break
            crc = buf[end - 2 : end]
            # adler32's low half is 1 + the byte sum while that sum stays below 65520 (at most 256
            # bytes before the checksum): the checksum in one C call
            s = ((_adler32(buf[pos : end - 2]) & 0xFFFF) - 1 if end - pos <= 258 else sum(buf[pos : end - 2])) & 0xFF
            if not (crc == HEX2[s] or crc == HEX2_LOWER[s]) or buf.find(b"#", pos + 1, end) >= 0:
                break
            append(_new_tuple(Frame, head[1] + (buf[pos + 10 : end - 2], None)))
            pos = end
        stats.frames += len(out)
        if pos < n_buf:
            pos = self._scan(buf, pos, out, final=False)
            if final:  # the rest as if the stream ended here
                pos = self._scan(buf, pos, out, final=True)
                if pos < n_buf:
                    self._discard(buf[pos:], out, WHY[END_OF_STREAM])
                pos = n_buf
            self._buf = buf[pos:]
            if decode is not None:
                return [decode(e) if type(e) is Frame else e for e in out]
            return out
        self._buf = b""
        return out if decode is None else list(map(decode, out))

    def _discard(self, raw: bytes, out: list[Any], why: str, kind: str = "garbage") -> None:
        junk = raw.translate(None, b"\r\n")  # line ends between frames are no news
        if not junk:
            return
        self.stats.bytes_discarded += len(junk)
        self.stats.resyncs += 1
        out.append(Diagnostic(kind, why, raw))

    def _oversize(self, buf: bytes, i: int, out: list[Any]) -> None:
        self.stats.oversize += 1
        self._discard(buf[i : i + 1], out, f"declared length above the {self.max_data_length}-byte bound", "oversize")

    def _bad_checksum(self, buf: bytes, i: int, end: int, nxt: int, out: list[Any]) -> None:
        """Drop the frame [i, end) whose checksum is wrong; scanning resumes at `nxt`."""
        stats = self.stats
        stats.bad_checksums += 1
        stats.bytes_discarded += nxt - i
        stats.resyncs += 1
        crc = buf[end - 2 : end]
        expected = checksum_text(buf[i : end - 2]).decode()
        out.append(Diagnostic("bad_checksum", f"checksum {crc.decode('latin-1')!r}, expected {expected!r}", buf[i:end]))

    def _c_event(self, buf: bytes, out: list[Any], code: int, start: int, end: int, nxt: int, frame: Any) -> None:
        """A rare event of the C scanner (anything but a good frame), turned into exactly the
        diagnostics and statistics the pure scan gives."""
        if code == OVERSIZE:
            self._oversize(buf, start, out)
        elif code == BAD_CHECKSUM:
            self._bad_checksum(buf, start, end, nxt, out)
        elif code == RECOVERED:
            self._emit_recovered((frame, end), buf, start, out)
        else:
            self._discard(buf[start:end], out, WHY[code], "bad_header" if code == BAD_HEADER else "garbage")

    def _frame_end(self, buf: bytes, i: int) -> int:
        """End offset of a frame starting at `i` (by its declared length), -1 if it cannot be a
        frame, -2 if more bytes are needed to tell, -3 if it claims more than the bound."""
        n_buf = len(buf)
        if n_buf < i + 10:
            return -1 if bad_prefix(buf, i, n_buf) else -2
        hdr = buf[i + 1 : i + 3]
        # bytes.isalnum() is ASCII-only: exactly the identifier rule, in one call
        if hdr not in HDR or buf[i + 3] not in ADDR or buf[i + 4] not in ADDR or not buf[i + 7 : i + 10].isalnum():
            return -1
        if hdr == b"TP" or hdr == b"tp":
            n = HEXVAL[buf[i + 5]]
            if n < 0 or buf[i + 6] not in RW:
                return -1
        elif hdr == b"tP":
            n = buf[i + 5]
            if buf[i + 6] not in RW:
                return -1
        else:
            n = (buf[i + 5] << 8) | buf[i + 6]
        if n > self.max_data_length:
            return -3
        return i + 12 + n

    def _valid_complete_at(self, buf: bytes, j: int) -> bool:
        end = self._frame_end(buf, j)
        if end < 0 or end > len(buf):
            return False
        return buf[end - 2 : end].upper() == HEX2[sum(buf[j : end - 2]) & 0xFF]

    def _inner_frame(self, buf: bytes, i: int, end: int, final: bool) -> int | None:
        """For a frame at `i` whose checksum is right: the start of the first valid frame that begins
        inside it (-1 if there is none, None if bytes still to come decide).

        Such a frame wins. The one at `i` then matched its checksum by chance (1 in 256 per
        candidate end) and came out of garbage: taking it would swallow the real frame inside it.
        A real frame holding a whole valid frame in its data is far less likely still: ASCII data
        never contain '#', and only TOPOTEK's 10- and 14-byte binary GPS/UAV payloads could."""
        n_buf = len(buf)
        j = buf.find(b"#", i + 1, end)
        while j >= 0:
            e = self._frame_end(buf, j)
            if e == -2 or e > n_buf:
                if not final:
                    return None
            elif e > 0 and self._valid_complete_at(buf, j):
                return j
            j = buf.find(b"#", j + 1, end)
        return -1

    def _scan(self, buf: bytes, pos: int, out: list[Any], final: bool) -> int:
        n_buf = len(buf)
        stats = self.stats
        while pos < n_buf:
            i = buf.find(b"#", pos)
            if i < 0:
                self._discard(buf[pos:], out, WHY[OUTSIDE])
                return n_buf
            if i > pos:
                self._discard(buf[pos:i], out, WHY[OUTSIDE])
                pos = i
            head = HEADERS.get(buf[i : i + 10])
            if head is not None:
                end = i + 12 + head[0] if head[0] <= self.max_data_length else -3
            else:
                end = self._frame_end(buf, i)
                if end >= 0:
                    head = remember_header(buf, i, end - i - 12)
            if end == -2:
                return i  # too few bytes to judge the header yet (flush() discards them)
            if end == -1:
                self._discard(buf[i : i + 1], out, WHY[BAD_HEADER], "bad_header")
                pos = i + 1
                continue
            if end == -3:
                self._oversize(buf, i, out)
                pos = i + 1
                continue
            if end > n_buf:
                # Incomplete: wait, unless a complete good frame already follows (then this frame
                # is either one whose length field claims too much, or garbage; waiting would
                # hold the good frame back).
                j = buf.find(b"#", i + 1)
                while j >= 0 and not self._valid_complete_at(buf, j):
                    j = buf.find(b"#", j + 1)
                if j < 0:
                    return i  # wait for the rest (flush() discards it)
                if self.recover_length and buf[i + 1 : i + 3] in ASCII_HDR:
                    rec = recover(buf, i, final=True)
                    if isinstance(rec, tuple):
                        pos = self._emit_recovered(rec, buf, i, out)
                        continue
                self._discard(buf[i:j], out, WHY[INCOMPLETE_FOLLOWED])
                pos = j
                continue
            crc = buf[end - 2 : end]
            s = sum(buf[i : end - 2]) & 0xFF
            if crc == HEX2[s] or crc == HEX2_LOWER[s]:
                inner = -1 if buf.find(b"#", i + 1, end) < 0 else self._inner_frame(buf, i, end, final)
                if inner is None:
                    return i  # a frame that starts inside this one is still arriving
                if inner >= 0:
                    self._discard(buf[i:inner], out, WHY[INNER_FRAME])
                    pos = inner
                    continue
                assert head is not None  # set with every end >= 0
                stats.frames += 1
                out.append(_new_tuple(Frame, head[1] + (buf[i + 10 : end - 2], None)))
                pos = end
                continue
            # Bad checksum at the declared length.
            if self.recover_length and buf[i + 1 : i + 3] in ASCII_HDR:
                rec = recover(buf, i, final)
                if rec is None:
                    return i  # a longer candidate may still complete: wait for bytes
                if isinstance(rec, tuple):
                    pos = self._emit_recovered(rec, buf, i, out)
                    continue
            # Drop this frame only: resume at the next '#' (a frame may start inside this one).
            nxt = buf.find(b"#", i + 1, end)
            if nxt < 0:
                nxt = end
            self._bad_checksum(buf, i, end, nxt, out)
            pos = nxt
        return pos

    def _emit_recovered(self, rec: tuple[Frame, int], buf: bytes, i: int, out: list[Any]) -> int:
        frame, rec_end = rec
        self.stats.frames += 1
        self.stats.length_recoveries += 1
        out.append(
            Diagnostic(
                "length_mismatch",
                f"length character says {frame.declared_length}, data has {len(frame.data)}; "
                "checksum proves the real length",
                buf[i:rec_end],
            )
        )
        out.append(frame)
        return rec_end


class PureFrameParser(FrameParser):
    """FrameParser on the pure Python path whatever is installed (differential tests, benchmarks)."""

    feed = FrameParser.feed
    feed_datagram = FrameParser.feed_datagram
    flush = FrameParser.flush
    feed_messages = FrameParser.feed_messages


# The fast path: the same four methods in C (the pure ones above stay the reference).
_fast = _speedups.parser_methods(Frame, {name: getattr(FrameParser, name) for name in _speedups.PARSER_METHODS})
if _fast is not None:
    for _name, _method in _fast.items():
        setattr(FrameParser, _name, _method)
