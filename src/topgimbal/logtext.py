"""Text a peer sent, made safe for a log line: `untrusted(value)`.

A string from the network, a file or a browser may hold lone surrogates (aiohttp decodes headers
with `surrogateescape`), control characters or a newline that forges a second log line. A lone
surrogate cannot be encoded as UTF-8: a UTF-8 log file drops the whole record and pytest-xdist's
report of it breaks. Every place a peer's string reaches a log call passes it through here: the
result is printable text, surrogates and controls written as backslash escapes, cut to a length.
A leaf every layer may use (like errors.py and logthrottle.py)."""

from __future__ import annotations

MAX_LOGGED_CHARS = 200  # a peer's string in a log line is cut to this many characters

# C0 controls and DEL as escapes (a newline would start a forged log line); tab kept readable
_CONTROLS = {c: f"\\x{c:02x}" for c in (*range(0x20), 0x7F)}
_CONTROLS.update({ord("\n"): "\\n", ord("\r"): "\\r", ord("\t"): "\\t"})


def untrusted(value: object, limit: int = MAX_LOGGED_CHARS) -> str:
    """`value` (usually a str from a peer) as printable, UTF-8-encodable text of at most about
    `limit` characters: lone surrogates and C0 controls as backslash escapes."""
    text = value if isinstance(value, str) else str(value)
    more = len(text) - limit
    safe = text[:limit].encode("utf-8", "backslashreplace").decode("utf-8").translate(_CONTROLS)
    return f"{safe}… (+{more} chars)" if more > 0 else safe
