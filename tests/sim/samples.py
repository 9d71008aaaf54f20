"""Real request values from the catalog's own metadata: each field's factory or neutral value, the
ends of its range, every value of its table. No hand-written values per command."""

from __future__ import annotations

import math
from datetime import datetime
from typing import Any

from topgimbal.protocol import Form
from topgimbal.protocol.fields import (
    BinInt,
    Bitrate,
    Codec,
    DecFloat,
    DecInt,
    Enum,
    Field,
    Geo,
    HexInt,
    IPv4Text,
    Literal,
    OneOf,
    RawData,
    Text,
    Timestamp,
)


def base_value(f: Field) -> Any:
    """What a field holds when the sample does not vary it: its factory value, its default, or its
    codec's neutral value."""
    for v in (f.factory, f.default):
        if v is not None:
            return v
    return f.codec.neutral()


def codec_values(codec: Codec) -> list[Any]:
    """Values worth sending: the range's ends, every table value, a typical text."""
    if isinstance(codec, Enum):
        return [v.name for v in codec.values]
    if isinstance(codec, OneOf):
        return codec_values(codec.tokens) + codec_values(codec.number)
    if isinstance(codec, (HexInt, BinInt, DecInt, DecFloat, Bitrate)):
        lo, hi = codec.min, codec.max
        assert lo is not None and hi is not None, codec
        if getattr(codec, "scale", 1) == 1 and not isinstance(codec, DecFloat):
            lo, hi = math.ceil(lo), math.floor(hi)
        out = [lo, hi]
        if getattr(codec, "none_tokens", ()):
            out.append(None)
        return out
    if isinstance(codec, Geo):
        return [-float(codec.limit), float(codec.limit), 22.5]
    if isinstance(codec, IPv4Text):
        return ["127.0.0.1", "255.255.255.255"]
    if isinstance(codec, RawData):
        return ["00" * max(1, codec.min_width), "AB" * min(codec.max_width, 15)]
    if isinstance(codec, Text):
        return ["V" * max(1, codec.min_len), "V1.2-" * (codec.max_len // 5)]
    if isinstance(codec, Timestamp):
        return [datetime(2025, 5, 29, 12, 34, 56), datetime(2031, 12, 31, 23, 59, 59)]
    if isinstance(codec, Literal):
        return [codec.text]
    raise AssertionError(f"no sample values for {codec!r}")


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
    if isinstance(codec, OneOf):
        return step_of(codec.number)
    if isinstance(codec, Geo):
        return codec.step / 2 + 1e-7
    return float(getattr(codec, "scale", 1)) / 2 + 1e-9


def same(codec: Codec, sent: Any, got: Any) -> bool:
    """`got` (decoded) is `sent` up to the codec's resolution."""
    if isinstance(sent, (int, float)) and isinstance(got, (int, float)) and not isinstance(sent, bool):
        return abs(float(sent) - float(got)) <= step_of(codec)
    if isinstance(sent, datetime) and isinstance(got, datetime):
        return abs((sent - got).total_seconds()) < 1
    if isinstance(codec, RawData) and isinstance(sent, str) and isinstance(got, str):
        return sent.upper() == got.upper()
    return bool(sent == got)


__all__ = ["base_value", "codec_values", "same", "samples"]
