"""The one rule that takes traffic on an undocumented port for TOP: `decode --pcap` (capture.py)
and the Wireshark dissector's heuristic (its Lua reads `lua_table()` from the generated tables).

A payload looks like TOP when, after at most MAX_LEADING_LINE_ENDS CR/LF bytes, it starts with a
TOP header (`#TP`, `#tp`, `#tP`, `#Tp`) followed by address letters (from protocol.frame: the
sender's and the receiver's) for as many of the next ADDRESS_BYTES bytes as the payload has (a TCP
segment may end right after the header). Before, the Lua wanted the two address letters and the
Python the header only, and they disagreed on 1 packet in 2,441 mutated ones (issue 27); the Lua
also looked at only 16 bytes, so a payload with more line ends before its header was TOP for one
and not for the other.
"""

from __future__ import annotations

from typing import Any

from ..protocol import frame

HEADERS = tuple(h.encode("ascii") for h in frame.HEADERS)  # the parser's
ADDRESS_LETTERS = frame.ADDRESSES.encode("ascii")
ADDRESS_BYTES = 2
# A sender may end lines with CR LF before a frame; more than this many line ends first is not TOP.
MAX_LEADING_LINE_ENDS = 8
HEAD_BYTES = MAX_LEADING_LINE_ENDS + len(HEADERS[0]) + ADDRESS_BYTES  # all the rule ever reads


def looks_like_top(payload: bytes) -> bool:
    """Whether a payload on an undocumented port is taken for TOP (see the module's rule)."""
    head = payload[:HEAD_BYTES]
    rest = head.lstrip(b"\r\n")
    if len(head) - len(rest) > MAX_LEADING_LINE_ENDS:
        return False
    if rest[:3] not in HEADERS:
        return False
    return all(b in ADDRESS_LETTERS for b in rest[3 : 3 + ADDRESS_BYTES])


def lua_table() -> dict[str, Any]:
    """The rule as data for the Lua dissector (`GEN.heuristic`)."""
    return {
        "headers": [h.decode("ascii") for h in HEADERS],
        "address_letters": ADDRESS_LETTERS.decode("ascii"),
        "address_bytes": ADDRESS_BYTES,
        "max_leading_line_ends": MAX_LEADING_LINE_ENDS,
        "head_bytes": HEAD_BYTES,
    }


__all__ = ["HEADERS", "MAX_LEADING_LINE_ENDS", "looks_like_top", "lua_table"]
