"""MAVLink 2 message signing: the key file and pymavlink's signing state (`--signing-key FILE`).

With a key the bridge signs everything it sends and refuses every message that is not signed with
the same key (unsigned, MAVLink 1, or a wrong signature) or that is a replay. `SignedStreams` keeps
the replay state the MAVLink signing spec describes: one timestamp per stream (link id, system,
component) for the whole node, whatever UDP address or connection a frame comes from, recorded only
after the signature is checked (a frame without the key changes nothing); a stream's timestamp
must grow, a new stream's must be at most a minute older than the newest seen, and no timestamp may
be more than MAX_FUTURE_S ahead of this computer's clock (one far ahead would otherwise be kept as
the stream's and refuse every later genuine frame). The key is the 32-byte secret of the spec.

The key file holds one of (checked in this order):
- 64 hexadecimal digits (optionally followed by a newline): the key itself, as QGC and MAVProxy
  show it;
- exactly 32 bytes that are not all printable text: the key itself, raw;
- anything else: a passphrase (UTF-8, a trailing newline ignored), whose SHA-256 is the key, as
  MAVProxy's `signing setup PASSPHRASE` and QGroundControl's signing key field make it.
"""

from __future__ import annotations

import hashlib
import logging
import stat
import string
from collections.abc import Callable
from pathlib import Path
from typing import Any

from ..clock import wall_time
from ..errors import TopGimbalError

log = logging.getLogger("topgimbal.mavlink")

KEY_BYTES = 32
MAX_FUTURE_S = 60.0  # a signed timestamp further ahead of this computer's clock is refused
NEW_STREAM_WINDOW = 6000 * 1000  # 1 minute in 10 us units: how far behind a new stream may start
MAX_SIGNED_STREAMS = 1024  # streams remembered (only frames signed with the key add one)
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
        key = key_from_bytes(data)
    except SigningKeyError as exc:
        raise SigningKeyError(f"signing key {str(p)!r}: {exc}") from None
    for warning in key_warnings(p, key):
        log.warning("signing key %r: %s", str(p), warning)
    return key


def key_warnings(path: Path, key: bytes) -> list[str]:
    """What is weak about a key and its file: an all-zero key (anyone guesses it), a file others
    may read or write (anyone on the computer can then sign)."""
    out = []
    if key == bytes(KEY_BYTES):
        out.append("the key is all zeros: anyone can sign with it")
    try:
        mode = path.stat().st_mode
    except OSError:
        return out
    if mode & (stat.S_IRWXG | stat.S_IRWXO):
        out.append(f"the file's mode is {stat.S_IMODE(mode):04o}: others may read it; chmod 600 it")
    return out


def timestamp_now(now_s: float | None = None) -> int:
    """The signing timestamp for a wall-clock time (10 us units since 2015-01-01)."""
    t = wall_time() if now_s is None else now_s
    return max(0, int((t - SIGNING_EPOCH_S) * 100_000))


class SignedStreams:
    """The node's signature and replay check (see the module docstring). `check(frame)` is None for
    a frame to accept, else why it is refused ("unsigned", "wrongly signed", "a replay", ...)."""

    def __init__(self, key: bytes, clock: Callable[[], float] = wall_time) -> None:
        self.key = key
        self.clock = clock
        self.streams: dict[tuple[int, int, int], int] = {}  # (link id, system, component) -> timestamp
        self.newest = timestamp_now(clock())  # as pymavlink: frames over a minute old are replays
        self.refused: dict[str, int] = {}

    def check(self, frame: bytes) -> str | None:
        why = self._check(frame)
        if why is not None:
            kind = why.split(":", 1)[0]
            self.refused[kind] = self.refused.get(kind, 0) + 1
        return why

    def _check(self, frame: bytes) -> str | None:
        if frame[:1] != b"\xfd":
            return "MAVLink 1 (unsigned)"
        if len(frame) < 12 + 13 or not frame[2] & 0x01:
            return "unsigned"
        digest = hashlib.sha256(self.key + bytes(frame[:-6])).digest()[:6]
        if digest != bytes(frame[-6:]):
            return "wrongly signed"
        link_id = frame[-13]
        ts = int.from_bytes(frame[-12:-6], "little")
        stream = (link_id, frame[5], frame[6])
        ahead_s = (ts - timestamp_now(self.clock())) / 100_000
        if ahead_s > MAX_FUTURE_S:
            return f"a timestamp from the future: {ahead_s:.0f} s ahead of this computer's clock (limit {MAX_FUTURE_S:g} s)"
        last = self.streams.get(stream)
        if last is not None and ts <= last:
            return "a replay: timestamp not newer than the stream's last"
        if last is None and ts + NEW_STREAM_WINDOW < self.newest:
            return "a replay: a new stream over a minute older than the newest timestamp"
        self.streams.pop(stream, None)
        self.streams[stream] = ts  # the newest last: the oldest stream is forgotten first
        if len(self.streams) > MAX_SIGNED_STREAMS:
            del self.streams[next(iter(self.streams))]
        self.newest = max(self.newest, ts)
        return None


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
    "SignedStreams",
    "SigningKeyError",
    "describe_refused",
    "key_from_bytes",
    "load_key",
    "require_signed",
    "sign_outgoing",
    "timestamp_now",
]
