"""MAVLink 2 message signing: the key file and pymavlink's signing state (`--signing-key FILE`).

With a key the bridge signs everything it sends and its parsers refuse every message that is not
signed with the same key (unsigned, MAVLink 1, or a wrong signature; pymavlink also refuses a
replay: a timestamp not newer than the last one of the same stream, or one over a minute older
than the newest seen). The key is the 32-byte secret of the MAVLink 2 signing spec.

The key file holds one of (checked in this order):
- 64 hexadecimal digits (optionally followed by a newline): the key itself, as QGC and MAVProxy
  show it;
- exactly 32 bytes that are not all printable text: the key itself, raw;
- anything else: a passphrase (UTF-8, a trailing newline ignored), whose SHA-256 is the key, as
  MAVProxy's `signing setup PASSPHRASE` and QGroundControl's signing key field make it.
"""

from __future__ import annotations

import hashlib
import string
from pathlib import Path
from typing import Any

from ..clock import wall_time
from ..errors import TopGimbalError

KEY_BYTES = 32
MAX_KEY_FILE_BYTES = 4096
# MAVLink signing timestamps count 10 microsecond units since 2015-01-01 00:00:00 UTC.
SIGNING_EPOCH_S = 1420070400
_PRINTABLE = set(string.printable.encode())


class SigningKeyError(TopGimbalError, ValueError):
    """A signing key file that cannot be used; the message says what is allowed."""


FORMS = "64 hex digits, 32 raw bytes, or a passphrase (its SHA-256 is the key)"


def key_from_bytes(data: bytes) -> bytes:
    """The 32-byte key a key file's contents stand for (see the module's rules)."""
    text = data.strip()
    if len(text) == 2 * KEY_BYTES and all(c in b"0123456789abcdefABCDEF" for c in text):
        return bytes.fromhex(text.decode())
    if len(data) == KEY_BYTES and not all(b in _PRINTABLE for b in data):
        return bytes(data)
    try:
        phrase = data.decode("utf-8").rstrip("\r\n")
    except UnicodeDecodeError:
        raise SigningKeyError(f"the key file is neither UTF-8 text nor 32 raw bytes: expected {FORMS}") from None
    if not phrase.strip():
        raise SigningKeyError(f"the key file is empty: expected {FORMS}")
    return hashlib.sha256(phrase.encode("utf-8")).digest()


def load_key(path: str | Path) -> bytes:
    """Read a key file; SigningKeyError naming the file and the problem otherwise."""
    p = Path(path)
    try:
        if not p.is_file():
            raise SigningKeyError(f"signing key {str(p)!r}: not a file (expected a file holding {FORMS})")
        with p.open("rb") as f:
            data = f.read(MAX_KEY_FILE_BYTES + 1)
    except OSError as exc:
        raise SigningKeyError(f"signing key {str(p)!r}: cannot read it ({exc.strerror or exc})") from None
    if len(data) > MAX_KEY_FILE_BYTES:
        raise SigningKeyError(f"signing key {str(p)!r}: longer than {MAX_KEY_FILE_BYTES} bytes (expected {FORMS})")
    try:
        return key_from_bytes(data)
    except SigningKeyError as exc:
        raise SigningKeyError(f"signing key {str(p)!r}: {exc}") from None


def timestamp_now(now_s: float | None = None) -> int:
    """The signing timestamp for a wall-clock time (10 us units since 2015-01-01)."""
    t = wall_time() if now_s is None else now_s
    return max(0, int((t - SIGNING_EPOCH_S) * 100_000))


def sign_outgoing(mav: Any, key: bytes, link_id: int = 0) -> None:
    """Make a pymavlink encoder sign what it sends."""
    mav.signing.secret_key = key
    mav.signing.link_id = link_id
    mav.signing.timestamp = timestamp_now()
    mav.signing.sign_outgoing = True


def require_signed(parser: Any, key: bytes) -> None:
    """Make a pymavlink parser refuse what is not signed with `key` (no unsigned exceptions):
    such messages come out as BAD_DATA with the reason "Invalid signature". Its clock starts now,
    so frames recorded over a minute ago are refused as replays."""
    parser.signing.secret_key = key
    parser.signing.allow_unsigned_callback = None
    parser.signing.timestamp = timestamp_now()


def describe_refused(data: bytes) -> tuple[str, int, int]:
    """What a refused frame was: ("unsigned" | "MAVLink 1" | "wrongly signed", sysid, compid)."""
    if data[:1] == b"\xfd" and len(data) >= 7:
        kind = "wrongly signed" if data[2] & 0x01 else "unsigned"
        return kind, data[5], data[6]
    if data[:1] == b"\xfe" and len(data) >= 5:
        return "MAVLink 1 (unsigned)", data[3], data[4]
    return "unreadable", 0, 0


__all__ = [
    "KEY_BYTES",
    "SigningKeyError",
    "describe_refused",
    "key_from_bytes",
    "load_key",
    "require_signed",
    "sign_outgoing",
    "timestamp_now",
]
