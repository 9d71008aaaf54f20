"""TCP stream reassembly for one direction of a connection: segments in any order in,
contiguous bytes out. Pure, no I/O.

Retransmitted and overlapping bytes are delivered once; a segment ahead of the next expected
sequence number waits until the hole is filled. At most `max_pending` bytes wait: beyond that (a
segment the capture missed) the hole is skipped and reported, so a lossy capture cannot grow the
buffer without bound.
"""

from __future__ import annotations

from dataclasses import dataclass, field

from .packets import TCP_SYN

MAX_PENDING = 256 * 1024
_MOD = 1 << 32


def _ahead(a: int, b: int) -> int:
    """How far sequence number `a` is past `b` (negative when behind), modulo 2^32."""
    d = (a - b) % _MOD
    return d - _MOD if d >= _MOD // 2 else d


@dataclass
class Delivery:
    """Bytes now contiguous; `gap` > 0 means that many bytes are missing before them."""

    data: bytes
    gap: int = 0


@dataclass
class TcpStream:
    max_pending: int = MAX_PENDING
    next_seq: int | None = None
    _pending: dict[int, bytes] = field(default_factory=dict)
    _pending_bytes: int = 0

    def add(self, seq: int, flags: int, payload: bytes) -> list[Delivery]:
        """One segment; returns what became contiguous (possibly after a skipped hole)."""
        if flags & TCP_SYN:
            self.next_seq = (seq + 1) % _MOD
            seq = (seq + 1) % _MOD
        if not payload:
            return []
        if self.next_seq is None:  # the capture started mid-connection
            self.next_seq = seq
        ahead = _ahead(seq, self.next_seq)
        if ahead > 0:
            old = self._pending.get(seq, b"")
            if len(payload) > len(old):
                self._pending[seq] = payload
                self._pending_bytes += len(payload) - len(old)
            out: list[Delivery] = []
            while self._pending_bytes > self.max_pending:
                out += self._skip_hole()
            return out
        out = [Delivery(payload[-ahead:])] if -ahead < len(payload) else []
        if out:
            self.next_seq = (self.next_seq + len(out[0].data)) % _MOD
        return out + self._drain()

    def finish(self) -> list[Delivery]:
        """End of the capture: whatever still waits, holes skipped, in order."""
        out: list[Delivery] = []
        while self._pending:
            out += self._skip_hole()
        return out

    def _drain(self) -> list[Delivery]:
        out: list[Delivery] = []
        progressed = True
        while progressed and self._pending:
            progressed = False
            assert self.next_seq is not None
            for seq in list(self._pending):
                ahead = _ahead(seq, self.next_seq)
                if ahead > 0:
                    continue
                data = self._pending.pop(seq)
                self._pending_bytes -= len(data)
                if -ahead < len(data):
                    chunk = data[-ahead:]
                    out.append(Delivery(chunk))
                    self.next_seq = (self.next_seq + len(chunk)) % _MOD
                progressed = True
        return out

    def _skip_hole(self) -> list[Delivery]:
        assert self.next_seq is not None
        base = self.next_seq
        seq = min(self._pending, key=lambda s: _ahead(s, base))
        gap = _ahead(seq, base)
        self.next_seq = seq
        out = self._drain()
        if out:
            out[0] = Delivery(out[0].data, gap)
        return out
