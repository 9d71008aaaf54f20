"""Capture files: pcap and pcapng, read and written. Bytes only: no protocol knowledge here.

The reader accepts both byte orders, microsecond and nanosecond pcap, and pcapng sections with
several interfaces (their own link types and timestamp resolutions; enhanced, simple and obsolete
packet blocks). It never raises on a damaged file past `open`: a truncated or corrupt record ends
the iteration with a `CaptureProblem` saying where and why, so a tool reports it and keeps what it
read. Limits: a record may hold at most `MAX_RECORD` bytes (a larger claim means corruption).
"""

from __future__ import annotations

import math
import struct
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import IO, BinaryIO

from ..errors import TopGimbalError

# Link-layer header types (https://www.tcpdump.org/linktypes.html) the packet decoder knows.
LINKTYPE_NULL = 0
LINKTYPE_ETHERNET = 1
LINKTYPE_RAW = 101
LINKTYPE_LOOP = 108
LINKTYPE_LINUX_SLL = 113
LINKTYPE_IPV4 = 228
LINKTYPE_IPV6 = 229
LINKTYPE_LINUX_SLL2 = 276

MAX_RECORD = 16 * 1024 * 1024
SNAPLEN = 262144

_PCAP_MAGIC_US = 0xA1B2C3D4
_PCAP_MAGIC_NS = 0xA1B23C4D
_PCAPNG_SHB = 0x0A0D0D0A
_PCAPNG_BOM = 0x1A2B3C4D
_IDB, _PB_OBSOLETE, _SPB, _EPB = 1, 2, 3, 6


class CaptureError(TopGimbalError, ValueError):
    """A file is not a pcap/pcapng capture, or cannot be written as one."""


@dataclass(frozen=True)
class CaptureRecord:
    """One captured packet: `number` counts from 1 in file order (as Wireshark numbers them)."""

    number: int
    ts: float  # seconds since the epoch
    linktype: int
    data: bytes
    orig_len: int


@dataclass(frozen=True)
class CaptureProblem:
    """Why reading stopped early or a block was skipped (`offset`: byte offset in the file)."""

    offset: int
    detail: str

    def __str__(self) -> str:
        return f"at byte {self.offset}: {self.detail}"


def read_capture(path: str | Path) -> Iterator[CaptureRecord | CaptureProblem]:
    """The packets of a pcap or pcapng file in file order, then a `CaptureProblem` if the file
    ends in a damaged or truncated record. Raises CaptureError only when the file cannot be read
    at all or is neither format (before yielding anything)."""
    try:
        fh = Path(path).open("rb")  # noqa: SIM115 - closed by the `with` below; open errors become CaptureError
    except OSError as exc:
        raise CaptureError(f"{path}: {exc.strerror or exc}") from None
    with fh:
        head = fh.read(4)
        if len(head) < 4:
            raise CaptureError(f"{path}: {len(head)} bytes is too short for a pcap or pcapng file")
        if struct.unpack("<I", head)[0] == _PCAPNG_SHB:
            yield from _read_pcapng(fh, head)
            return
        for order in ("<", ">"):
            magic = struct.unpack(order + "I", head)[0]
            if magic in (_PCAP_MAGIC_US, _PCAP_MAGIC_NS):
                yield from _read_pcap(fh, order, 1e-9 if magic == _PCAP_MAGIC_NS else 1e-6)
                return
        raise CaptureError(
            f"{path}: not a pcap or pcapng file (starts with {head.hex()}; pcap starts with a1b2c3d4 or "
            "a1b23c4d in either byte order, pcapng with 0a0d0d0a)"
        )


def _read_pcap(fh: BinaryIO, order: str, tick: float) -> Iterator[CaptureRecord | CaptureProblem]:
    rest = fh.read(20)
    if len(rest) < 20:
        yield CaptureProblem(4, "file header truncated")
        return
    _vmaj, _vmin, _zone, _sig, _snap, linktype = struct.unpack(order + "HHiIII", rest)
    linktype &= 0x0FFFFFFF  # the upper bits may carry FCS information
    offset, number = 24, 0
    rec = struct.Struct(order + "IIII")
    while True:
        head = fh.read(16)
        if not head:
            return
        if len(head) < 16:
            yield CaptureProblem(offset, f"record header truncated ({len(head)} of 16 bytes)")
            return
        sec, frac, incl, orig = rec.unpack(head)
        if incl > MAX_RECORD:
            yield CaptureProblem(offset, f"record claims {incl} bytes (corrupt; limit {MAX_RECORD})")
            return
        data = fh.read(incl)
        if len(data) < incl:
            yield CaptureProblem(offset, f"record truncated ({len(data)} of {incl} bytes)")
            return
        number += 1
        yield CaptureRecord(number, sec + frac * tick, linktype, data, orig)
        offset += 16 + incl


@dataclass
class _Interface:
    linktype: int
    tick: float
    offset_s: int


def _read_pcapng(fh: BinaryIO, first: bytes) -> Iterator[CaptureRecord | CaptureProblem]:
    order = "<"
    interfaces: list[_Interface] = []
    offset, number = 0, 0
    pending = first
    while True:
        head = pending + fh.read(8 - len(pending))
        pending = b""
        if not head:
            return
        if len(head) < 8:
            yield CaptureProblem(offset, f"block header truncated ({len(head)} of 8 bytes)")
            return
        btype = struct.unpack(order + "I", head[:4])[0]
        if btype == _PCAPNG_SHB:
            bom = fh.read(4)
            if len(bom) < 4:
                yield CaptureProblem(offset, "section header truncated")
                return
            if struct.unpack("<I", bom)[0] == _PCAPNG_BOM:
                order = "<"
            elif struct.unpack(">I", bom)[0] == _PCAPNG_BOM:
                order = ">"
            else:
                yield CaptureProblem(offset, f"section header has byte-order magic {bom.hex()}, not 1a2b3c4d")
                return
            length = struct.unpack(order + "I", head[4:8])[0]
            body_len = length - 12
            problem = _bad_block_length(length, 28)
            if problem:  # checked before reading: a corrupt length must not size an allocation
                yield CaptureProblem(offset, f"section header: {problem}")
                return
            body = bom + fh.read(body_len - 4)
            interfaces = []  # interface ids are per section
        else:
            length = struct.unpack(order + "I", head[4:8])[0]
            body_len = length - 12
            problem = _bad_block_length(length, 12)
            if problem:
                yield CaptureProblem(offset, f"block type 0x{btype:08x}: {problem}")
                return
            body = fh.read(body_len)
        if body_len < 0 or len(body) < body_len:
            yield CaptureProblem(offset, "block truncated")
            return
        trailer = fh.read(4)
        if len(trailer) < 4 or struct.unpack(order + "I", trailer)[0] != length:
            yield CaptureProblem(offset, "block truncated or its trailing length does not match")
            return
        problem = None
        if btype == _IDB:
            problem = _interface(body, order, interfaces)
        elif btype in (_EPB, _PB_OBSOLETE, _SPB):
            got = _packet(btype, body, order, interfaces)
            if isinstance(got, str):
                problem = got
            else:
                number += 1
                yield CaptureRecord(number, *got)
        if problem:
            yield CaptureProblem(offset, problem)
            if btype != _IDB:
                number += 1  # Wireshark numbers a damaged packet too; keep numbers aligned
        offset += length


def _bad_block_length(length: int, least: int) -> str | None:
    if length < least or length % 4 or length > MAX_RECORD:
        return f"block length {length}: must be a multiple of 4 in {least}..{MAX_RECORD}"
    return None


def _interface(body: bytes, order: str, interfaces: list[_Interface]) -> str | None:
    if len(body) < 8:
        return "interface description block too short"
    linktype = struct.unpack(order + "H", body[:2])[0]
    tick, offset_s = 1e-6, 0
    pos = 8
    while pos + 4 <= len(body):
        code, n = struct.unpack(order + "HH", body[pos : pos + 4])
        value = body[pos + 4 : pos + 4 + n]
        if code == 0:
            break
        if code == 9 and n >= 1:  # if_tsresol: 10^-x, or 2^-x with the top bit set
            r = value[0]
            tick = 2.0 ** -(r & 0x7F) if r & 0x80 else 10.0**-r
        elif code == 14 and n >= 8:  # if_tsoffset: seconds to add
            offset_s = struct.unpack(order + "q", value[:8])[0]
        pos += 4 + n + (-n % 4)
    interfaces.append(_Interface(linktype, tick, offset_s))
    return None


def _packet(btype: int, body: bytes, order: str, interfaces: list[_Interface]) -> tuple[float, int, bytes, int] | str:
    if btype == _SPB:
        if not interfaces:
            return "simple packet block before any interface description"
        if len(body) < 4:
            return "simple packet block too short"
        orig = struct.unpack(order + "I", body[:4])[0]
        return 0.0, interfaces[0].linktype, body[4 : 4 + orig], orig
    if btype == _EPB:
        if len(body) < 20:
            return "enhanced packet block too short"
        iface, hi, lo, cap, orig = struct.unpack(order + "IIIII", body[:20])
        data_at = 20
    else:
        if len(body) < 20:
            return "packet block too short"
        iface, _drops, hi, lo, cap, orig = struct.unpack(order + "HHIIII", body[:20])
        data_at = 20
    if iface >= len(interfaces):
        return f"packet on interface {iface}, but only {len(interfaces)} are described"
    if data_at + cap > len(body):
        return f"packet claims {cap} captured bytes, its block holds {len(body) - data_at}"
    itf = interfaces[iface]
    ts = ((hi << 32) | lo) * itf.tick + itf.offset_s
    return ts, itf.linktype, body[data_at : data_at + cap], orig


# -- writing ---------------------------------------------------------------------------------------

MAX_TIME_S = 0xFFFFFFFF  # pcap stores whole seconds in 32 bits: 2106-02-07


def capture_micros(ts: float) -> int:
    """`ts` in whole microseconds, or CaptureError when pcap's 32-bit seconds cannot hold it."""
    if not (isinstance(ts, (int, float)) and math.isfinite(ts) and 0 <= ts < MAX_TIME_S + 1):
        raise CaptureError(f"time {ts!r} cannot be written: a capture holds 0..{MAX_TIME_S} s since 1970")
    return min(round(ts * 1_000_000), (MAX_TIME_S + 1) * 1_000_000 - 1)


class PcapWriter:
    """Writes a classic pcap file (microsecond timestamps, little-endian). By default every record
    is flushed as written, so a reader (or Wireshark) sees packets while the capture runs; with
    `flush_each=False` records wait in a `BUFFER`-byte buffer until `flush()` (or the buffer fills),
    one write for many packets: for a writer on a busy path that flushes on a timer."""

    BUFFER = 64 * 1024

    def __init__(
        self, dest: str | Path | IO[bytes], linktype: int = LINKTYPE_ETHERNET, *, flush_each: bool = True
    ) -> None:
        self.linktype = linktype
        self.flush_each = flush_each
        self._own = isinstance(dest, (str, Path))
        self._fh: IO[bytes] | None
        if isinstance(dest, (str, Path)):
            self._fh = Path(dest).open("wb", buffering=self.BUFFER)  # noqa: SIM115 - owned; closed by close()
        else:
            self._fh = dest
        self.packets = 0
        self._start()
        self.flush()  # the file header at once: the file is a valid (empty) capture from the start

    def _start(self) -> None:
        self._out(struct.pack("<IHHiIII", _PCAP_MAGIC_US, 2, 4, 0, 0, SNAPLEN, self.linktype))

    def _out(self, data: bytes) -> None:
        if self._fh is None:
            raise CaptureError("the capture file is closed")
        self._fh.write(data)

    def _record(self, data: bytes) -> None:
        self._out(data)
        self.packets += 1
        if self.flush_each:
            self.flush()

    def write(self, ts: float, packet: bytes) -> None:
        """Append one packet captured at `ts` (seconds since the epoch; CaptureError for a time
        the format cannot hold: not finite, negative, or past 2106)."""
        micros = capture_micros(ts)
        sec, usec = divmod(micros, 1_000_000)
        self._record(struct.pack("<IIII", sec, usec, len(packet), len(packet)) + packet)

    def flush(self) -> None:
        """Hand what waits to the operating system (a reader then sees whole records)."""
        if self._fh is not None:
            self._fh.flush()

    def close(self) -> None:
        if self._fh is not None:
            if self._own:
                self._fh.close()
            else:
                self._fh.flush()
            self._fh = None

    def __enter__(self) -> PcapWriter:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()


class PcapngWriter(PcapWriter):
    """Writes pcapng: one section, one interface (microsecond resolution), enhanced packet blocks."""

    def _start(self) -> None:
        shb = struct.pack("<IHHq", _PCAPNG_BOM, 1, 0, -1)
        self._out(self._block(_PCAPNG_SHB, shb))
        self._out(self._block(_IDB, struct.pack("<HHI", self.linktype, 0, SNAPLEN)))

    def _block(self, btype: int, body: bytes) -> bytes:
        body += b"\0" * (-len(body) % 4)
        length = len(body) + 12
        return struct.pack("<II", btype, length) + body + struct.pack("<I", length)

    def write(self, ts: float, packet: bytes) -> None:
        micros = capture_micros(ts)
        head = struct.pack("<IIIII", 0, micros >> 32, micros & 0xFFFFFFFF, len(packet), len(packet))
        self._record(self._block(_EPB, head + packet))


def open_writer(path: str | Path, linktype: int = LINKTYPE_ETHERNET, *, flush_each: bool = True) -> PcapWriter:
    """A pcapng writer for `*.pcapng`, a pcap writer otherwise."""
    try:
        if str(path).lower().endswith(".pcapng"):
            return PcapngWriter(path, linktype, flush_each=flush_each)
        return PcapWriter(path, linktype, flush_each=flush_each)
    except OSError as exc:
        raise CaptureError(f"{path}: {exc.strerror or exc}") from None
