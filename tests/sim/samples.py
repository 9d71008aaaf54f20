"""Real request values from the catalog's own metadata: each field's factory or neutral value, the
ends of its range, every value of its table. No hand-written values per command."""

from __future__ import annotations

import math
from datetime import datetime
from typing import Any

from topgimbal.protocol import Form
from topgimbal.protocol.fields import Codec, Field


def base_value(f: Field) -> Any:
    """What a field holds when the sample does not vary it: its factory value, its default, or its
    codec's neutral value."""
    for v in (f.factory, f.default):
        if v is not None:
            return v
    return f.codec.neutral()


def _numbers(d: dict[str, Any]) -> list[Any]:
    lo, hi = d["min"], d["max"]
    if d.get("step", 1) >= 1:
        lo, hi = math.ceil(lo - 1e-9), math.floor(hi + 1e-9)
    return [lo, hi]


def codec_values(codec: Codec) -> list[Any]:
    """Values worth sending, read from the codec's own description: the range's ends, every table
    value, a typical text of each length limit, "no value" where the codec has a spelling for it."""
    d = codec.describe()
    kind = d["kind"]
    if kind == "enum":
        return [v["name"] for v in d["values"]]
    if kind == "enum_or_number":
        return [v["name"] for v in d["tokens"]] + _numbers(d["number"])
    if kind == "number":
        return _numbers(d) + ([None] if getattr(codec, "none_tokens", ()) else [])
    if kind == "coordinate":
        limit = float(getattr(codec, "limit", 90))
        return [-limit, limit, 22.5]
    if kind == "ipv4":
        return ["127.0.0.1", "255.255.255.255"]
    if kind == "raw":
        return ["00" * max(1, codec.min_width), "AB" * min(codec.max_width, 15)]
    if kind == "text":
        return ["V" * max(1, codec.min_width), "V1.2-" * (codec.max_width // 5)]
    if kind == "datetime":
        return [datetime(2025, 5, 29, 12, 34, 56), datetime(2031, 12, 31, 23, 59, 59)]
    if kind == "literal":
        return [codec.neutral()]
    raise AssertionError(f"no sample values for a {kind} codec ({d['codec']})")


def samples(form: Form) -> list[dict[str, Any]]:
    """Every field's base value, then one field at a time through its values (the rest at their
    base): each range end and table value is sent once, without a combinatorial blow-up."""
    if form.const is not None:
        return [{}]
    base = {f.name: base_value(f) for f in form.fields}
    out = [base]
    for f in form.fields:
        for v in codec_values(f.codec):
            if v != base[f.name] or type(v) is not type(base[f.name]):
                out.append({**base, f.name: v})
    return out


def step_of(codec: Codec) -> float:
    """Half a step of the codec: how far a decoded number may be from what was sent."""
    d = codec.describe()
    step = d.get("number", d).get("step", 1e-6 if d["kind"] == "coordinate" else 1)
    return float(step) / 2 + 1e-7


def same(codec: Codec, sent: Any, got: Any) -> bool:
    """`got` (decoded) is `sent` up to the codec's resolution."""
    if isinstance(sent, (int, float)) and isinstance(got, (int, float)) and not isinstance(sent, bool):
        return abs(float(sent) - float(got)) <= step_of(codec)
    if isinstance(sent, datetime) and isinstance(got, datetime):
        return abs((sent - got).total_seconds()) < 1
    if codec.kind == "raw" and isinstance(sent, str) and isinstance(got, str):
        return sent.upper() == got.upper()
    return bool(sent == got)


__all__ = ["base_value", "codec_values", "same", "samples"]
