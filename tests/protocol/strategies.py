"""Hypothesis strategies generated from the codecs' own metadata: valid values of any codec in the
catalog, and hostile values of every type a caller might pass."""

from __future__ import annotations

import math
import string
from datetime import datetime
from typing import Any

from hypothesis import strategies as st

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
from topgimbal.protocol.fields.text import FRAME_BYTES

PRINTABLE_NO_HASH = "".join(c for c in string.printable if c.isprintable() and c != "#")


def _floats(lo: float, hi: float, step: float = 0.0) -> st.SearchStrategy[float]:
    # Edges matter most: the ends of the range, and values halfway between two steps (where
    # rounding decides), sampled explicitly besides any float in the range.
    parts = [
        st.floats(min_value=lo, max_value=hi, allow_nan=False, allow_infinity=False),
        st.sampled_from([lo, hi, (lo + hi) / 2]),
    ]
    if step:
        k_lo, k_hi = math.floor(lo / step), math.ceil(hi / step)
        parts.append(
            st.tuples(st.integers(k_lo, k_hi), st.sampled_from([0.5, -0.5, 0.4999999, 0.5000001])).map(
                lambda kf: min(hi, max(lo, (kf[0] + kf[1]) * step))
            )
        )
    return st.one_of(*parts)


def values(codec: Codec) -> st.SearchStrategy[Any]:
    """Values `codec.encode` must accept (in range, of the right type)."""
    if isinstance(codec, (HexInt, BinInt)):
        assert codec.min is not None and codec.max is not None
        base: st.SearchStrategy[Any] = _floats(codec.min, codec.max, codec.scale)
        if codec.scale == 1:
            base = st.integers(math.ceil(codec.min), math.floor(codec.max))
        if isinstance(codec, HexInt) and codec.none_tokens:
            base = st.one_of(st.none(), base)
        return base
    if isinstance(codec, DecInt):
        assert codec.max is not None
        return (
            st.integers(math.ceil(codec.min), math.floor(codec.max))
            if codec.scale == 1
            else _floats(codec.min, codec.max)
        )
    if isinstance(codec, DecFloat):
        base = _floats(codec.min, codec.max, codec.scale)
        return st.one_of(st.none(), base) if codec.none_tokens else base
    if isinstance(codec, Bitrate):
        return st.integers(codec.min, codec.max)
    if isinstance(codec, Enum):
        return st.sampled_from([v.name for v in codec.values])
    if isinstance(codec, OneOf):
        return st.one_of(values(codec.tokens), values(codec.number))
    if isinstance(codec, Text):
        return st.text(alphabet=PRINTABLE_NO_HASH, min_size=codec.min_len, max_size=codec.max_len)
    if isinstance(codec, IPv4Text):
        return st.ip_addresses(v=4).map(str)
    if isinstance(codec, RawData):
        data = st.binary(min_size=codec.min_width, max_size=min(codec.max_width, 16))
        if not codec.binary:
            data = data.filter(lambda b: not FRAME_BYTES.intersection(b))
        return data.map(bytes.hex)
    if isinstance(codec, Geo):
        return _floats(-float(codec.limit), float(codec.limit), codec.step)
    if isinstance(codec, Timestamp):
        lo, hi = (2000, 2099) if "%y" in codec.layout else (1000, 9999)
        return st.datetimes(min_value=datetime(lo, 1, 1), max_value=datetime(hi, 12, 31, 23, 59, 59, 999999))
    if isinstance(codec, Literal):
        return st.just(codec.text)
    raise AssertionError(f"no strategy for {codec!r}")


def resolution(codec: Codec) -> float:
    """How far a decoded number may be from the value encoded (half a step, plus float noise)."""
    if isinstance(codec, OneOf):
        return resolution(codec.number)
    if isinstance(codec, Geo):
        return codec.step / 2 + 1e-7
    step = getattr(codec, "scale", 1)
    return float(step) / 2 + 1e-9


def close(codec: Codec, sent: Any, got: Any) -> bool:
    """Whether `got` (decoded) is `sent` up to the codec's resolution."""
    if isinstance(sent, bool) or isinstance(got, bool):
        return sent == got
    if isinstance(sent, (int, float)) and isinstance(got, (int, float)):
        return abs(float(sent) - float(got)) <= resolution(codec)
    if isinstance(sent, datetime) and isinstance(got, datetime):
        keep = 10000 if "%f2" in getattr(codec, "layout", "") else 1000000
        return sent.replace(microsecond=sent.microsecond // keep * keep if keep < 1000000 else 0) == got
    if isinstance(codec, Enum) and isinstance(sent, str):
        v = codec.lookup(sent)
        return v is not None and v.name == got
    if isinstance(codec, RawData) and isinstance(sent, str):
        return bytes.fromhex(sent).hex() == got
    return bool(sent == got)


# Anything a caller might hand an encoder: wrong types, huge and special numbers, hostile text.
HOSTILE = st.one_of(
    st.none(),
    st.booleans(),
    st.integers(),
    st.sampled_from([10**400, -(10**400), 2**64, -(2**63) - 1, 1.7e308, -1.7e308, 5e-324]),
    st.floats(),  # nan, inf, huge, tiny
    st.text(max_size=40),
    st.sampled_from(["#TPUG2wPTZ006A", "ab#cd", "V1\r\n#tp", "x\x00y", "é", "", " ", "1e400", "nan", "inf", "0x10"]),
    st.binary(max_size=20),
    st.datetimes(),
    st.lists(st.integers(), max_size=3),
    st.dictionaries(st.text(max_size=3), st.integers(), max_size=2),
)
