"""One JSON value per line (JSON Lines), readable by any line splitter. A leaf every layer may use.

`json.dumps(..., ensure_ascii=False)` writes U+0085 (NEL), U+2028 and U+2029 raw inside strings:
valid JSON, but Python's `str.splitlines` (and JavaScript before ES2019) breaks the line there and
the record in two (issue 35.7). `line()` writes them as `\\u` escapes; every other character stays
as it is (a decoded frame's Chinese text stays readable). Inside a JSON text these characters can
only occur in strings (they are not JSON whitespace), so replacing them is exact."""

from __future__ import annotations

import json
from typing import Any

LINE_BREAKERS = {"\u0085": "\\u0085", "\u2028": "\\u2028", "\u2029": "\\u2029"}


def line(obj: Any, **kwargs: Any) -> str:
    """`obj` as one line of JSON, without a line breaker any reader splits on."""
    text = json.dumps(obj, ensure_ascii=False, **kwargs)
    for raw, escaped in LINE_BREAKERS.items():
        if raw in text:
            text = text.replace(raw, escaped)
    return text
