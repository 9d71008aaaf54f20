"""The frame scanner's tables and checks (parser.py): which bytes may stand where in a header, hex
digit values, the checksum's hex forms, the bounded cache of headers already judged valid (headers
repeat: the same command, addresses and length), and length recovery (`recover`: the module
docstring of parser.py says when it applies). Stdlib only; no state but that cache (cleared when
full)."""

from __future__ import annotations

from .frame import Frame

HEXVAL = [-1] * 256
for _i, _c in enumerate(b"0123456789ABCDEF"):
    HEXVAL[_c] = _i
for _i, _c in enumerate(b"abcdef"):
    HEXVAL[_c] = 10 + _i
ADDR = frozenset(b"UMDEPG")
RW = frozenset(b"rw")
# An identifier is three ASCII letters or digits (every command in both documents, and every one
# real clients send); anything else after a header means the '#' did not start a frame.
IDENT = frozenset(b"ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789")
HDR = {b"TP": "#TP", b"tp": "#tp", b"tP": "#tP", b"Tp": "#Tp"}
ASCII_HDR = frozenset((b"TP", b"tp"))
SEPARATORS = frozenset(b"\r\n")
HEX2 = [b"%02X" % i for i in range(256)]
# A frame's ten header bytes -> (declared data length, the Frame's first five items): headers repeat
# (the same command, addresses and length), so a valid one is judged once. Bounded: cleared when full.
HEADERS: dict[bytes, tuple[int, tuple[str, str, str, str, str]]] = {}
HEADERS_MAX = 4096
HEX2_LOWER = [b"%02x" % i for i in range(256)]
ASCII_MAX_TOTAL = 12 + 15


def remember_header(buf: bytes, i: int, n: int) -> tuple[int, tuple[str, str, str, str, str]]:
    """The header at `i` (valid, declaring `n` data bytes) as HEADERS keeps it."""
    hdr = buf[i + 1 : i + 3]
    rw = "" if hdr == b"Tp" else chr(buf[i + 6])
    head = (n, (HDR[hdr], chr(buf[i + 3]), chr(buf[i + 4]), rw, buf[i + 7 : i + 10].decode("ascii")))
    if len(HEADERS) >= HEADERS_MAX:
        HEADERS.clear()
    HEADERS[buf[i : i + 10]] = head
    return head


def bad_prefix(buf: bytes, i: int, n_buf: int) -> bool:
    """True if the bytes already after the '#' at `i` rule out a frame (so garbage is dropped at
    once instead of being held waiting for bytes that cannot make it a frame)."""
    if n_buf <= i + 2:
        return n_buf > i + 1 and buf[i + 1] not in b"Tt"
    hdr = buf[i + 1 : i + 3]
    if hdr not in HDR:
        return True
    for k in (3, 4):
        if n_buf > i + k and buf[i + k] not in ADDR:
            return True
    if n_buf > i + 5 and (hdr == b"TP" or hdr == b"tp") and HEXVAL[buf[i + 5]] < 0:
        return True
    if n_buf > i + 6 and hdr != b"Tp" and buf[i + 6] not in RW:
        return True
    return any(n_buf > i + k and buf[i + k] not in IDENT for k in (7, 8, 9))


def recover(buf: bytes, i: int, final: bool) -> tuple[Frame, int] | bool | None:
    """The frame at `i` at another length whose checksum is right and which ends exactly where
    the next thing starts (`#`, CR, LF, or the end of a datagram when `final`). False if there
    is none, None if bytes still to come decide it.

    Requiring the exact fit is what makes recovery safe when bytes trickle in one at a time: a
    shorter length whose checksum matches by chance (1 in 256 per length) is not taken just
    because the buffer happens to end there."""
    n_buf = len(buf)
    limit = min(n_buf, i + ASCII_MAX_TOTAL)
    boundary = None
    # A '#' even inside the header or identifier bounds the frame (then no length fits).
    for k in range(i + 1, limit):
        b = buf[k]
        if b == 0x23 or b == 0x0D or b == 0x0A:
            boundary = k
            break
    if boundary is None:
        if not final and n_buf < i + ASCII_MAX_TOTAL:
            return None
        boundary = limit
    n = boundary - i - 12
    declared = HEXVAL[buf[i + 5]]
    if n < 0 or n > 15 or n == declared:
        return False
    end = boundary
    data = buf[i + 10 : end - 2]
    if buf[end - 2 : end].upper() != HEX2[sum(buf[i : end - 2]) & 0xFF]:
        return False
    if not all(0x20 <= b < 0x7F for b in data):
        return False
    frame = Frame(
        HDR[buf[i + 1 : i + 3]],
        chr(buf[i + 3]),
        chr(buf[i + 4]),
        chr(buf[i + 6]),
        buf[i + 7 : i + 10].decode("latin-1"),
        data,
        declared,
    )
    return frame, end
