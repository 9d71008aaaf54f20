"""Lua literals for the generated dissector's tables (dissector.py): deterministic, text as UTF-8
bytes, wire bytes kept byte for byte, identifiers bare unless Lua reserves them."""

from __future__ import annotations

import math
import re
from collections.abc import Iterable, Mapping

from ..errors import TopGimbalError


class DissectorError(TopGimbalError):
    """The catalog holds something the dissector generator does not know how to show."""


_IDENT = re.compile(r"^[A-Za-z_][A-Za-z0-9_]*$")
_LUA_KEYWORDS = frozenset(
    [
        "and",
        "break",
        "do",
        "else",
        "elseif",
        "end",
        "false",
        "for",
        "function",
        "goto",
        "if",
        "in",
        "local",
        "nil",
        "not",
        "or",
        "repeat",
        "return",
        "then",
        "true",
        "until",
        "while",
    ]
)


def _lua_str(s: str | bytes) -> str:
    """Text (labels, descriptions) goes out as UTF-8, which Wireshark shows; wire bytes are
    passed as `bytes` and kept byte for byte."""
    raw = s.encode("utf-8") if isinstance(s, str) else s
    out = []
    for b in raw:
        if b in (0x22, 0x5C):
            out.append("\\" + chr(b))
        elif 0x20 <= b < 0x7F:
            out.append(chr(b))
        else:
            out.append(f"\\{b:03d}")
    return '"' + "".join(out) + '"'


def to_lua(obj: object, indent: str = "") -> str:
    """A Lua literal for JSON-like data (dict keys are strings or ints); deterministic."""
    if obj is None:
        return "nil"
    if isinstance(obj, bool):
        return "true" if obj else "false"
    if isinstance(obj, int):
        return str(obj)
    if isinstance(obj, float):
        if math.isnan(obj) or math.isinf(obj):
            raise DissectorError(f"{obj!r} has no Lua literal")
        return repr(obj)
    if isinstance(obj, (str, bytes)):
        return _lua_str(obj)
    inner = indent + " "
    if isinstance(obj, Mapping):
        parts = []
        for k, v in obj.items():
            if v is None:
                continue
            if isinstance(k, str) and _IDENT.match(k) and k not in _LUA_KEYWORDS:
                key = k
            elif isinstance(k, (str, bytes)):
                key = f"[{_lua_str(k)}]"
            else:
                key = f"[{int(k)}]"
            parts.append(f"{key}={to_lua(v, inner)}")
        return _wrap(parts, indent)
    if isinstance(obj, Iterable):
        return _wrap([to_lua(v, inner) for v in obj], indent)
    raise DissectorError(f"cannot write {type(obj).__name__} as Lua")


def _wrap(parts: list[str], indent: str) -> str:
    one = "{" + ", ".join(parts) + "}"
    if len(one) + len(indent) <= 110 and "\n" not in one:
        return one
    inner = indent + " "
    return "{\n" + ",\n".join(inner + p for p in parts) + "\n" + indent + "}"
