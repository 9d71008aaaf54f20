"""Representative valid values of every codec, from the codecs' own metadata.

`example_values(codec)` gives values that survive encode -> decode unchanged (the ends of a range,
a middle value, every enum value, null where the codec has one). Tests (every form of the catalog
through the simulator, the Wireshark dissector, the C core), docs and tools that need a sample
frame of a form read them here, so no one keeps a second table of example values."""

from __future__ import annotations

from datetime import datetime
from typing import Any

from .fields import (
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
from .forms import Form


def example_values(codec: Codec) -> list[Any]:
    """Values that must survive encode -> decode unchanged (min, max, a middle value...)."""
    if isinstance(codec, (HexInt, DecInt, BinInt)):
        lo, hi = codec.min, codec.max
        if lo is None or hi is None:
            raise TypeError(f"{codec!r} has no range")
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
        return [v.name for v in codec.tokens.values] + example_values(codec.number)
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
    raise TypeError(f"no example values for codec {type(codec).__name__}: add a case to protocol/examples.py")


def values_equal(a: Any, b: Any) -> bool:
    """Whether a decoded value is the example it came from (floats to 1e-6, times to 1/100 s)."""
    if isinstance(a, float) or isinstance(b, float):
        return a is not None and b is not None and abs(float(a) - float(b)) < 1e-6
    if isinstance(a, datetime) and isinstance(b, datetime):
        return a.replace(microsecond=a.microsecond // 10000 * 10000) == b
    return bool(a == b)


def example_fields(form: Form) -> dict[str, Any]:
    """One valid value per field of `form` (the first example of each codec)."""
    return {f.name: example_values(f.codec)[0] for f in form.fields}
