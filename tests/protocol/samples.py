"""Representative valid values for every codec, generated from the codecs' own metadata."""

from __future__ import annotations

from datetime import datetime
from typing import Any

from topgimbal.protocol.fields import (
    BinInt,
    Bitrate,
    Codec,
    DecFloat,
    DecInt,
    Enum,
    Geo,
    HexInt,
    IPv4Text,
    Literal,
    OneOf,
    RawData,
    Text,
    Timestamp,
)


def samples(codec: Codec) -> list[Any]:
    """Values that must survive encode -> decode unchanged (min, max, a middle value...)."""
    if isinstance(codec, (HexInt, DecInt, BinInt)):
        lo, hi = codec.min, codec.max
        assert lo is not None and hi is not None
        step = codec.scale
        mid = round(round(((lo + hi) / 2) / step) * step, 6)
        vals: list[Any] = [lo, hi, mid]
        if isinstance(codec, HexInt) and codec.none_tokens:
            vals.append(None)
        return vals
    if isinstance(codec, DecFloat):
        vals = [codec.min, codec.max, round((codec.min + codec.max) / 2, codec.decimals)]
        if codec.none_tokens:
            vals.append(None)
        return vals
    if isinstance(codec, Enum):
        return [v.name for v in codec.values]
    if isinstance(codec, OneOf):
        return [v.name for v in codec.tokens.values] + samples(codec.number)
    if isinstance(codec, Text):
        return ["V" + "1" * (max(codec.min_len, 1) - 1), "x" * codec.max_len]
    if isinstance(codec, IPv4Text):
        return ["127.0.0.5", "0.0.0.0", "255.255.255.255"]
    if isinstance(codec, Geo) and codec.style == "dm":
        return [0.0, 22.5, -33.8688, codec.limit - 0.5]
    if isinstance(codec, Geo):
        return [0.0, 22.123456, -113.654321 if codec.axis == "lon" else -45.5]
    if isinstance(codec, Timestamp):
        return [datetime(2024, 5, 6, 7, 8, 9), datetime(2099, 12, 31, 23, 59, 58)]
    if isinstance(codec, Bitrate):
        return [50, 1234, 2000, 8000, 99999]
    if isinstance(codec, RawData):
        return ["41" * (codec.width or 3)]
    if isinstance(codec, Literal):
        return [codec.text]
    raise AssertionError(f"no samples for {codec!r}")


def equal(a: Any, b: Any) -> bool:
    if isinstance(a, float) or isinstance(b, float):
        return a is not None and b is not None and abs(float(a) - float(b)) < 1e-6
    if isinstance(a, datetime) and isinstance(b, datetime):
        return a.replace(microsecond=a.microsecond // 10000 * 10000) == b
    return bool(a == b)
