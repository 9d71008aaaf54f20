"""What every codec is: the `Codec` base class and the checks the codec families share.

A codec converts one field between its value in user units and the bytes of a frame's data, and
describes itself as data. The contract every codec keeps (a property test holds it to it over the
whole catalog):

- `encode(value, name)` returns bytes or raises `FieldValueError` (a ValueError) naming the field,
  the value and what is allowed; never another exception, whatever the value's type or size;
- `decode(raw)` returns the value or raises ValueError (never KeyError, IndexError, OverflowError);
- `decode(encode(v))` is `v` up to the codec's resolution, and encoding it again gives the same bytes;
- text that reaches the wire is printable ASCII without `#` (no frame can be injected through a
  value), except in codecs that are binary by definition (`BinInt`, `RawData(binary=True)`).

Public attributes read by other tools (the C table generator, the console, generated docs) are
stable: `kind`, `width`, `min_width`, `max_width`, `unit`, and per family `signed`, `scale`,
`min`, `max`, `values`, `none_tokens`. `describe()` gives them as JSON-able data; its `codec` key
names the class (`HexInt`, `Geo`, ...), the precise layout for generators that need it.
"""

from __future__ import annotations

import math
from datetime import datetime
from typing import ClassVar, TypedDict, Union

from ...errors import FieldValueError

# A field's value in user units, as the codecs decode it (and take it back): numbers, enum names
# and text, a Timestamp's datetime, None for a "no value" token. Message.fields hold these.
FieldValue = Union[int, float, str, datetime, None]  # noqa: UP007  (a runtime alias, Python 3.10)
# What `to_json` makes of one: JSON has no datetime.
JsonScalar = Union[int, float, str, bool, None]  # noqa: UP007


class EnumValueDescription(TypedDict):
    raw: str
    name: str
    label: str
    idempotent: bool
    vendor_term: str


class _CodecDescriptionBase(TypedDict):
    kind: str
    codec: str
    width: int | None
    unit: str
    allowed: str


class CodecDescription(_CodecDescriptionBase, total=False):
    """`Codec.describe()`: every codec's keys, then its family's (numbers: min, max, step; enums:
    values; enum-or-number: tokens and number)."""

    min: float
    max: float
    step: float
    values: list[EnumValueDescription]
    tokens: list[EnumValueDescription]
    number: CodecDescription


# Ints beyond this are rejected before any float conversion (10**400 would overflow a float).
_INT_LIMIT = 1 << 63


def decimals_of(scale: float) -> int:
    """Decimal places a value in steps of `scale` needs (0.01 -> 2, 1 -> 0)."""
    if scale >= 1 and float(scale).is_integer():
        return 0
    return max(0, -math.floor(math.log10(scale) + 1e-9)) if scale < 1 else 0


def to_number(value: object, name: str, codec: Codec) -> float:
    """`value` as a finite float, or FieldValueError naming what `codec` allows (built only on
    error). bool is refused (True is not a number a user means); numeric text is accepted."""
    if isinstance(value, bool):
        raise FieldValueError(name, value, codec.allowed())
    if isinstance(value, int):
        if not -_INT_LIMIT < value < _INT_LIMIT:
            raise FieldValueError(name, value, codec.allowed())
        return float(value)
    if isinstance(value, str):
        if len(value) > 64:
            raise FieldValueError(name, value, codec.allowed())
        try:
            value = float(value)
        except ValueError:
            raise FieldValueError(name, value, codec.allowed()) from None
    if not isinstance(value, float) or math.isnan(value) or math.isinf(value):
        raise FieldValueError(name, value, codec.allowed())
    return value


def fmt(v: float | None) -> str:
    return "?" if v is None else f"{v:g}"


def in_range(v: float, lo: float, hi: float) -> bool:
    """Range check with a tolerance far below any codec's step (float noise at the edges)."""
    return lo - 1e-9 <= v <= hi + 1e-9


class Codec:
    """Base class. `width` is the fixed number of data bytes, or None for a variable-width codec
    that takes the rest of the data (`min_width`..`max_width`)."""

    kind: ClassVar[str] = "raw"
    width: int | None = None
    unit: str = ""

    @property
    def min_width(self) -> int:
        return self.width if self.width is not None else 0

    @property
    def max_width(self) -> int:
        return self.width if self.width is not None else 0xFF

    def encode(self, value: object, name: str = "value") -> bytes:
        raise NotImplementedError

    def decode(self, raw: bytes) -> FieldValue:
        raise NotImplementedError

    def allowed(self) -> str:
        """What values `encode` accepts, in words (used by errors, CLI help and docs)."""
        raise NotImplementedError

    def parse_text(self, text: str) -> FieldValue:
        """A value from command-line text."""
        return text

    def to_json(self, value: FieldValue) -> JsonScalar:
        return value.isoformat() if isinstance(value, datetime) else value

    def neutral(self) -> FieldValue:
        """A valid value with no particular meaning: what a stored setting holds when the catalog
        names no factory value (`Field.factory`). 0 where the range has it, else its nearest end."""
        return None

    def describe(self) -> CodecDescription:
        """Metadata as JSON-able data; number codecs add `min`, `max` and `step` (user units)."""
        d: CodecDescription = {
            "kind": self.kind,
            "codec": type(self).__name__,
            "width": self.width,
            "unit": self.unit,
            "allowed": self.allowed(),
        }
        if self.kind == "number":
            lo, hi = getattr(self, "min", None), getattr(self, "max", None)
            if isinstance(lo, (int, float)) and not isinstance(lo, bool):
                d["min"] = lo
            if isinstance(hi, (int, float)) and not isinstance(hi, bool):
                d["max"] = hi
            scale, decimals = getattr(self, "scale", None), getattr(self, "decimals", None)
            if isinstance(scale, (int, float)) and scale:
                d["step"] = scale
            elif isinstance(decimals, int):
                d["step"] = 10.0**-decimals
        return d


def clamp_neutral(lo: float | None, hi: float | None) -> float:
    lo = 0.0 if lo is None else lo
    hi = 0.0 if hi is None else hi
    return max(lo, min(hi, 0.0))


__all__ = [
    "Codec",
    "CodecDescription",
    "EnumValueDescription",
    "FieldValue",
    "JsonScalar",
    "clamp_neutral",
    "decimals_of",
    "fmt",
    "in_range",
    "to_number",
]
