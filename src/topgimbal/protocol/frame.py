"""The frame envelope: header, addresses, length, control, identifier, data, checksum.

Pure and I/O-free. A `Frame` is immutable; `Frame.to_bytes()` is the only encoder of the envelope
and `dissect()` the only strict decoder of one frame (the streaming parser reuses its tables).

Layout (TOPOTEK §二.1, SkyDroid §2.2)::

    #TP | #tp   src dst LEN rw ID1ID2ID3 DATA... CRC CRC     LEN = one hex ASCII char, 0..15
    #tP         src dst LEN rw ID... DATA... CRC CRC         LEN = one raw byte, 0..255
    #Tp         src dst LENHI LENLO ID... DATA... CRC CRC    16-bit raw length in the LEN and
                                                             control positions (no r/w; see errata)

The checksum is the sum of every byte before it, mod 256, as two upper-case hex characters.
"""

from __future__ import annotations

import re
from dataclasses import dataclass
from typing import NamedTuple

from ..errors import ChecksumError, FrameError, LengthError

HEADERS = ("#TP", "#tp", "#tP", "#Tp")
ASCII_HEADERS = ("#TP", "#tp")
ADDRESSES = "UMDEPG"
HOST_ADDRESSES = "UP"
DEVICE_ADDRESSES = "MDEG"
ADDRESS_NAMES = {
    "U": "uart/udp host",
    "M": "lens (zoom, focus)",
    "D": "system and image",
    "E": "auxiliary device (thermal, laser)",
    "P": "network host",
    "G": "gimbal",
}
MAX_LENGTH = {"#TP": 0x0F, "#tp": 0x0F, "#tP": 0xFF, "#Tp": 0xFFFF}

_HEX_UPPER = [b"%02X" % i for i in range(256)]
# Frame.text(): printable ASCII stays, every other byte becomes \xNN (the backslash too, as \\,
# so the text maps back to exactly one byte string).
_ESCAPES = {i: f"\\x{i:02x}" for i in range(256) if not 0x20 <= i < 0x7F}
_ESCAPES[0x5C] = "\\\\"
_IDENT_CHARS = frozenset("ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789")


_ESCAPE = re.compile(r"\\(\\|x[0-9A-Fa-f]{2})")


def bytes_from_text(text: str) -> bytes:
    """The bytes of a frame written as `Frame.text()` writes it: `\\xNN` is that byte, `\\\\` a
    backslash, everything else latin-1 (a backslash before anything else stays as typed). What
    `topgimbal encode` prints for a binary payload (TOPOTEK GPS, UAV, LOC) decodes again this way.
    UnicodeEncodeError for characters beyond latin-1."""
    if "\\" not in text:
        return text.encode("latin-1")
    return _ESCAPE.sub(lambda m: "\\" if m.group(1) == "\\" else chr(int(m.group(1)[1:], 16)), text).encode("latin-1")


def is_identifier(ident: str) -> bool:
    """Three ASCII letters or digits: every identifier the documents and real clients use."""
    return len(ident) == 3 and all(c in _IDENT_CHARS for c in ident)


def checksum(data: bytes) -> int:
    """The TOP checksum: sum of every byte, mod 256."""
    return sum(data) & 0xFF


def checksum_text(data: bytes) -> bytes:
    """The two upper-case hex characters that end a frame whose body is `data`."""
    return _HEX_UPPER[sum(data) & 0xFF]


class Frame(NamedTuple):
    """One TOP frame. Immutable (a tuple), cheap to build on the parser's hot path.

    `declared_length` is None when the length character equals `len(data)`; otherwise it holds the
    value on the wire (a recovered frame with a wrong length character, or a simulator quirk), and
    `to_bytes()` reproduces it.
    """

    header: str
    src: str
    dst: str
    rw: str  # "r" or "w"; "" for #Tp frames, whose control position carries the length
    ident: str
    data: bytes = b""
    declared_length: int | None = None

    @property
    def length(self) -> int:
        return len(self.data) if self.declared_length is None else self.declared_length

    def body(self) -> bytes:
        """Every byte before the checksum."""
        n = self.length
        h = self.header
        if h in ASCII_HEADERS:
            if not 0 <= n <= 0x0F:
                raise LengthError(f"{h} frames carry 0..15 data bytes, not {n} (use #tP/#Tp)")
            length = b"0123456789ABCDEF"[n : n + 1] + self.rw.encode("ascii")
        elif h == "#tP":
            if not 0 <= n <= 0xFF:
                raise LengthError(f"#tP frames carry 0..255 data bytes, not {n}")
            length = bytes((n,)) + self.rw.encode("ascii")
        elif h == "#Tp":
            if not 0 <= n <= 0xFFFF:
                raise LengthError(f"#Tp frames carry 0..65535 data bytes, not {n}")
            length = n.to_bytes(2, "big")
        else:
            raise FrameError(f"header {h!r} is not one of {', '.join(HEADERS)}")
        return (h + self.src + self.dst).encode("ascii") + length + self.ident.encode("ascii") + self.data

    def to_bytes(self) -> bytes:
        body = self.body()
        return body + _HEX_UPPER[sum(body) & 0xFF]

    def __bytes__(self) -> bytes:
        return self.to_bytes()

    def swapped(self, *, data: bytes | None = None, rw: str | None = None, header: str | None = None) -> Frame:
        """The reply to this frame: addresses swapped, optionally new data / control / header."""
        return Frame(
            header=self.header if header is None else header,
            src=self.dst,
            dst=self.src,
            rw=self.rw if rw is None else rw,
            ident=self.ident,
            data=self.data if data is None else data,
        )

    def text(self) -> str:
        """The frame as printable text: bytes outside printable ASCII (binary data, control
        characters) shown as \\xNN escapes. Never raises, even for a frame whose parts are not
        valid (built by hand): logs and consoles show whatever they are given."""
        try:
            raw = self.to_bytes()
        except (FrameError, UnicodeError, TypeError, ValueError, AttributeError):
            parts = (self.header, self.src, self.dst, str(self.length), self.rw, self.ident)
            raw = "".join(str(p) for p in parts).encode("latin-1", "backslashreplace") + bytes(self.data or b"") + b"??"
        return raw.decode("latin-1").translate(_ESCAPES)

    def __str__(self) -> str:
        return self.text()


def make_frame(
    ident: str,
    data: bytes | str = b"",
    *,
    src: str = "U",
    dst: str = "G",
    rw: str = "w",
    header: str | None = None,
) -> Frame:
    """Build a frame, validating every part and choosing the header when not given."""
    if isinstance(data, str):
        data = data.encode("latin-1")
    if not isinstance(ident, str) or not is_identifier(ident):
        raise FrameError(f"identifier must be 3 ASCII letters or digits, got {ident!r}")
    for role, addr in (("src", src), ("dst", dst)):
        if len(addr) != 1 or addr not in ADDRESSES:
            raise FrameError(f"{role} address must be one of {', '.join(ADDRESSES)}, got {addr!r}")
    if header is None:
        header = "#TP" if len(data) == 2 else ("#tp" if len(data) <= 0x0F else "#tP")
    if header not in HEADERS:
        raise FrameError(f"header must be one of {', '.join(HEADERS)}, got {header!r}")
    if header == "#Tp":
        # #Tp frames carry their 16-bit length where the control character would be: they are
        # writes (reports) by construction, so a read cannot be spelled with this header.
        if rw not in ("", "w"):
            raise FrameError(f"a #Tp frame has no control character and is always a write; cannot send {rw!r}")
        rw = ""
    elif rw not in ("r", "w"):
        raise FrameError(f"control must be 'r' (query) or 'w' (set/control), got {rw!r}")
    if len(data) > MAX_LENGTH[header]:
        raise LengthError(f"{header} frames carry at most {MAX_LENGTH[header]} data bytes, got {len(data)}")
    return Frame(header, src, dst, rw, ident, data)


@dataclass(frozen=True)
class Dissection:
    """Everything readable in one candidate frame, even when it is bad (for `decode` and tools)."""

    raw: bytes
    frame: Frame | None  # None unless the frame is complete and its checksum right
    error: str | None
    header: str | None = None
    src: str | None = None
    dst: str | None = None
    length: int | None = None
    rw: str | None = None
    ident: str | None = None
    data: bytes | None = None
    checksum: str | None = None
    expected_checksum: str | None = None
    anomaly: str | None = None

    @property
    def ok(self) -> bool:
        return self.frame is not None and self.error is None


def _header_length(raw: bytes) -> tuple[int, int, int]:
    """(declared data length, offset of identifier, offset of first data byte) for a raw frame."""
    h = raw[:3].decode("latin-1")
    if h in ASCII_HEADERS:
        c = raw[5:6]
        try:
            n = int(c, 16)
        except ValueError:
            raise LengthError(f"length character {c!r} is not a hex digit 0-F") from None
        return n, 7, 10
    if h == "#tP":
        return raw[5], 7, 10
    return int.from_bytes(raw[5:7], "big"), 7, 10


def dissect(raw: bytes, *, recover_length: bool = True) -> Dissection:
    """Strictly decode exactly one frame (trailing CR LF allowed), reporting what is wrong.

    With `recover_length`, a frame whose length character disagrees with the data but whose
    checksum proves the real length (a real C12 sends `#tpDU3rVER0105025A`) is accepted, with
    `anomaly` saying so.
    """
    raw = raw.rstrip(b"\r\n")
    if not raw.startswith(b"#"):
        return Dissection(raw, None, "a frame starts with '#'")
    h = raw[:3].decode("latin-1")
    if h not in HEADERS:
        return Dissection(raw, None, f"header {h!r} is not one of {', '.join(HEADERS)}")
    if len(raw) < 12:
        return Dissection(raw, None, f"{len(raw)} bytes is shorter than the smallest frame (12)", header=h)
    src, dst = chr(raw[3]), chr(raw[4])
    bad_addr = [a for a in (src, dst) if a not in ADDRESSES]
    if bad_addr:
        return Dissection(
            raw, None, f"address {bad_addr[0]!r} is not one of {', '.join(ADDRESSES)}", header=h, src=src, dst=dst
        )
    try:
        n, id_at, data_at = _header_length(raw)
    except LengthError as exc:
        return Dissection(raw, None, str(exc), header=h, src=src, dst=dst)
    rw = "" if h == "#Tp" else chr(raw[6])
    ident = raw[id_at : id_at + 3].decode("latin-1")
    if not is_identifier(ident):
        return Dissection(
            raw, None, f"identifier {ident!r} is not 3 ASCII letters or digits", header=h, src=src, dst=dst
        )

    data = raw[data_at:-2]
    crc = raw[-2:].decode("latin-1")
    expected = checksum_text(raw[:-2]).decode("ascii")
    parts = dict(header=h, src=src, dst=dst, length=n, rw=rw, ident=ident, data=data, checksum=crc)
    if rw not in ("r", "w", ""):
        return Dissection(raw, None, f"control {rw!r} is not 'r' or 'w'", expected_checksum=expected, **parts)  # type: ignore[arg-type]
    if crc.upper() != expected:
        return Dissection(
            raw,
            None,
            f"bad checksum: {crc!r} on the wire, expected {expected!r}",
            expected_checksum=expected,
            **parts,  # type: ignore[arg-type]
        )
    anomaly = None
    declared: int | None = None
    if n != len(data):
        msg = f"length character says {n} data bytes, the frame has {len(data)}"
        if not (recover_length and h in ASCII_HEADERS):
            return Dissection(raw, None, msg, expected_checksum=expected, **parts)  # type: ignore[arg-type]
        anomaly = msg + " (checksum proves the real length; accepted)"
        declared = n
    frame = Frame(h, src, dst, rw, ident, data, declared)
    return Dissection(raw, frame, None, expected_checksum=expected, anomaly=anomaly, **parts)  # type: ignore[arg-type]


def parse_frame(raw: bytes | str) -> Frame:
    """Decode exactly one frame or raise FrameError / ChecksumError / LengthError saying why."""
    if isinstance(raw, str):
        raw = raw.encode("latin-1")
    d = dissect(raw)
    if d.frame is None:
        _raise_for(d)
    assert d.frame is not None
    return d.frame


def _raise_for(d: Dissection) -> None:
    """The specific FrameError for a dissection that failed."""
    err = d.error or "not a frame"
    if err.startswith("bad checksum"):
        raise ChecksumError(err, expected=d.expected_checksum or "", found=d.checksum or "")
    if "length" in err:
        raise LengthError(err)
    raise FrameError(err)


def complete_frame(text: str | bytes) -> bytes:
    """A frame typed by hand: returned as is when complete and right; with its checksum appended
    when the text is exactly header..data (length character matching the data); otherwise
    FrameError saying what is wrong (a wrong checksum is never silently replaced)."""
    raw = (text.encode("latin-1") if isinstance(text, str) else bytes(text)).strip()
    d = dissect(raw, recover_length=False)
    if d.ok:
        return raw
    h = raw[:3].decode("latin-1")
    if h in ASCII_HEADERS and len(raw) >= 10:
        try:
            n = int(raw[5:6], 16)
        except ValueError:
            n = -1
        if len(raw) == 10 + n:
            full = raw + checksum_text(raw)
            if dissect(full, recover_length=False).ok:
                return full
    _raise_for(d)
    raise AssertionError("unreachable")
