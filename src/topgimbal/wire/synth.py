"""Conversations written as a capture: the `CaptureWriter` turns "these bytes went from A to B
over UDP/TCP at time t" into packets of a pcap/pcapng file that Wireshark and tshark read like a
real capture (the proxy, `pcap from-log` and the tests write through it; the console will too).

TCP connections get a three-way handshake before their first data, sequence and acknowledgement
numbers that add up, and a FIN exchange on `close_tcp()`, so Wireshark reassembles them.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

from ..clock import wall_time
from .packets import TCP_ACK, TCP_FIN, TCP_PSH, TCP_SYN, Endpoint, build_packet
from .pcapfile import LINKTYPE_ETHERNET, CaptureError, PcapWriter, capture_micros, open_writer

MAX_SEGMENT = 65000  # bytes of TCP payload per packet (an IPv4 packet holds at most 65535)
MAX_DATAGRAM = 65507  # bytes of UDP payload in one IPv4 packet (65535 - IP and UDP headers)


@dataclass
class _Tcp:
    client: Endpoint
    server: Endpoint
    seq: dict[Endpoint, int]


class CaptureWriter:
    """Packets between endpoints, written to `path` (pcapng if it ends in .pcapng). Addresses
    are IPv4 or IPv6 text; each call may pass `ts` (seconds since the epoch, default now).
    `flush_each=False`: packets wait in a buffer until `flush()` (see `PcapWriter`)."""

    def __init__(self, path: str | Path, *, flush_each: bool = True) -> None:
        self.path = Path(path)
        self._out: PcapWriter = open_writer(path, LINKTYPE_ETHERNET, flush_each=flush_each)
        self._tcp: dict[frozenset[Endpoint], _Tcp] = {}
        self._ident = 0
        self._last_ts: float | None = None

    @property
    def packets(self) -> int:
        return self._out.packets

    def _write(self, ts: float, transport: str, src: Endpoint, dst: Endpoint, payload: bytes, **kw: int) -> None:
        self._ident = (self._ident + 1) & 0xFFFF
        packet = build_packet(transport, src, dst, payload, ident=self._ident, **kw)
        self._last_ts = ts
        self._out.write(ts, packet)

    @staticmethod
    def _time(ts: float | None) -> float:
        """`ts` (now when None), checked before anything is written: a bad time writes nothing."""
        ts = wall_time() if ts is None else ts
        capture_micros(ts)
        return ts

    def udp(self, src: Endpoint, dst: Endpoint, payload: bytes, ts: float | None = None) -> None:
        """One datagram. CaptureError (nothing written) for more than MAX_DATAGRAM bytes, which no
        IP packet holds, or a time a capture cannot hold."""
        if len(payload) > MAX_DATAGRAM:
            raise CaptureError(f"a {len(payload)}-byte datagram cannot be written: UDP holds at most {MAX_DATAGRAM}")
        self._write(self._time(ts), "udp", src, dst, payload)

    def tcp(
        self, src: Endpoint, dst: Endpoint, payload: bytes, ts: float | None = None, *, client: Endpoint | None = None
    ) -> None:
        """Stream bytes from `src` to `dst`, one segment per 65000 bytes. The first call for a pair
        opens the connection from `client` (default: `src`)."""
        ts = self._time(ts)
        opener, other = (src, dst) if client is None or client == src else (dst, src)
        conn = self._connection(opener, other, ts)
        for at in range(0, len(payload), MAX_SEGMENT):
            piece = payload[at : at + MAX_SEGMENT]
            self._write(ts, "tcp", src, dst, piece, seq=conn.seq[src], ack=conn.seq[dst], flags=TCP_PSH | TCP_ACK)
            conn.seq[src] = (conn.seq[src] + len(piece)) & 0xFFFFFFFF

    def _connection(self, client: Endpoint, server: Endpoint, ts: float) -> _Tcp:
        src, dst = client, server
        key = frozenset((src, dst))
        conn = self._tcp.get(key)
        if conn is None:
            # Fixed initial sequence numbers: the same session gives the same file.
            conn = _Tcp(src, dst, {src: 1000, dst: 500000})
            self._tcp[key] = conn
            self._write(ts, "tcp", src, dst, b"", seq=999, ack=0, flags=TCP_SYN)
            self._write(ts, "tcp", dst, src, b"", seq=499999, ack=1000, flags=TCP_SYN | TCP_ACK)
            self._write(ts, "tcp", src, dst, b"", seq=1000, ack=500000, flags=TCP_ACK)
        return conn

    def close_tcp(self, src: Endpoint, dst: Endpoint, ts: float | None = None) -> None:
        """`src` closes the connection (FIN from each side, acknowledged)."""
        ts = self._time(ts)
        conn = self._tcp.pop(frozenset((src, dst)), None)
        if conn is None:
            return
        a, b = conn.seq[src], conn.seq[dst]
        self._write(ts, "tcp", src, dst, b"", seq=a, ack=b, flags=TCP_FIN | TCP_ACK)
        self._write(ts, "tcp", dst, src, b"", seq=b, ack=a + 1, flags=TCP_FIN | TCP_ACK)
        self._write(ts, "tcp", src, dst, b"", seq=a + 1, ack=b + 1, flags=TCP_ACK)

    def flush(self) -> None:
        self._out.flush()

    def close(self) -> None:
        """Close open TCP connections (FIN exchange) and the file."""
        for conn in list(self._tcp.values()):
            self.close_tcp(conn.client, conn.server, self._last_ts)
        self._out.close()

    def __enter__(self) -> CaptureWriter:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()
