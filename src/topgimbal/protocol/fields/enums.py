"""Enumerations: a table of wire spellings named in user space, and enum-or-number fields."""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import ClassVar, Union

from ...errors import FieldValueError
from .base import Codec, CodecDescription, FieldValue

# Values that mean "leave as it is" rather than a setting of their own (SkyDroid `N` lens slots).
KEEP_NAMES = frozenset({"null"})


@dataclass(frozen=True)
class EnumValue:
    """One wire spelling. `label` is English, for people; `vendor_term` the vendor document's own
    word for it (often Chinese), kept for a tooltip; `idempotent` is False for toggles and relative
    steps (never retried, and not a stored value)."""

    raw: str
    name: str
    label: str = ""
    idempotent: bool = True
    vendor_term: str = ""


@dataclass(frozen=True)
class Enum(Codec):
    """A value from a table of wire spellings, named in user space (`follow`, `white_hot`)."""

    width: int
    values: tuple[EnumValue, ...] = ()
    kind: ClassVar[str] = "enum"
    _by_raw: Mapping[bytes, EnumValue] = field(default_factory=dict, init=False, repr=False, compare=False)
    _by_name: Mapping[str, EnumValue] = field(default_factory=dict, init=False, repr=False, compare=False)
    # the spellings as a decode error lists them, joined once: a failed decode must stay cheap
    _table: str = field(default="", init=False, repr=False, compare=False)

    def __post_init__(self) -> None:
        by_raw: dict[bytes, EnumValue] = {}
        by_name: dict[str, EnumValue] = {}
        for v in self.values:
            if len(v.raw) != self.width or not v.raw.isascii() or not v.raw.isprintable() or "#" in v.raw:
                raise ValueError(f"enum spelling {v.raw!r} is not {self.width} printable characters")
            if v.name in by_name or v.raw.encode("ascii") in by_raw:
                raise ValueError(f"enum value {v.name!r} ({v.raw}) defined twice")
            by_raw[v.raw.encode("ascii")] = v
            by_name[v.name] = v
        for v in self.values:  # some firmware spells hex in lower case
            by_raw.setdefault(v.raw.lower().encode("ascii"), v)
        object.__setattr__(self, "_by_raw", by_raw)
        object.__setattr__(self, "_by_name", by_name)
        object.__setattr__(self, "_table", ", ".join(x.raw for x in self.values))

    def allowed(self) -> str:
        return "one of " + ", ".join(f"{v.name} ({v.raw})" for v in self.values)

    def lookup(self, value: object) -> EnumValue | None:
        """The table entry for a name, a wire spelling, a non-negative int (its hex spelling) or an
        EnumValue; None when there is none (bool is never a value of a table)."""
        if isinstance(value, EnumValue):
            return value if value in self.values else None
        if isinstance(value, str):
            if len(value) > 64:
                return None
            v = self._by_name.get(value) or self._by_name.get(value.lower().replace("-", "_"))
            if v is None and value.isascii():
                v = self._by_raw.get(value.encode("ascii"))
            return v
        if isinstance(value, int) and not isinstance(value, bool) and 0 <= value < 16**self.width:
            return self._by_raw.get(b"%0*X" % (self.width, value))
        return None

    def encode(self, value: object, name: str = "value") -> bytes:
        v = self.lookup(value)
        if v is None:
            raise FieldValueError(name, value, self.allowed())
        return v.raw.encode("ascii")

    def decode(self, raw: bytes) -> str:
        v = self._by_raw.get(raw)
        if v is None:
            raise ValueError(f"{raw!r} is not in the table ({self._table})")
        return v.name

    def is_idempotent(self, raw: bytes) -> bool:
        v = self._by_raw.get(raw)
        return True if v is None else v.idempotent

    def plain_values(self) -> list[EnumValue]:
        """The values that are settings of their own: no toggles, steps or "keep" spellings."""
        return [v for v in self.values if v.idempotent and v.name not in KEEP_NAMES]

    def neutral(self) -> str | None:
        plain = self.plain_values()
        return (plain[0] if plain else self.values[0]).name if self.values else None

    def describe(self) -> CodecDescription:
        d = super().describe()
        d["values"] = [
            {"raw": v.raw, "name": v.name, "label": v.label, "idempotent": v.idempotent, "vendor_term": v.vendor_term}
            for v in self.values
        ]
        return d


EnumSpec = Union[str, tuple[str, str], tuple[str, str, str]]  # noqa: UP007  (a runtime alias)


def enum(width: int, table: Mapping[str, EnumSpec], *, toggles: str | tuple[str, ...] = ()) -> Enum:
    """Shorthand: `enum(2, {"00": "stop", "01": ("up", "Nudge up"), "05": ("center", "Centre", "回中")},
    toggles=("01",))`: a name, or (name, English label), or (name, label, vendor term)."""
    if isinstance(toggles, str):
        toggles = (toggles,)
    vals = []
    for raw, spec in table.items():
        if isinstance(spec, str):
            name, label, term = spec, spec.replace("_", " "), ""
        elif len(spec) == 2:
            name, label, term = spec[0], spec[1], ""
        else:
            name, label, term = spec[0], spec[1], spec[2]
        vals.append(EnumValue(raw, name, label, raw not in toggles, term))
    return Enum(width, tuple(vals))


ON_OFF = enum(2, {"00": "off", "01": "on"})


@dataclass(frozen=True)
class OneOf(Codec):
    """Either a token from an enum or a number (TOPOTEK DZM: `0A` = step in, `25` = 2.5x). The token
    table and the number must not share a spelling; tokens are tried first when decoding."""

    tokens: Enum
    number: Codec
    kind: ClassVar[str] = "enum_or_number"
    width: int | None = field(init=False, default=None)

    def __post_init__(self) -> None:
        object.__setattr__(self, "width", self.tokens.width)
        if self.number.width != self.tokens.width:
            raise ValueError("OneOf: the tokens and the number must have the same width")

    def allowed(self) -> str:
        return f"{self.number.allowed()}, or {self.tokens.allowed()}"

    def encode(self, value: object, name: str = "value") -> bytes:
        tokenish = isinstance(value, EnumValue) or (isinstance(value, str) and not _numeric(value))
        if tokenish and self.tokens.lookup(value) is not None:
            return self.tokens.encode(value, name)
        try:
            return self.number.encode(value, name)
        except FieldValueError:
            raise FieldValueError(name, value, self.allowed()) from None

    def decode(self, raw: bytes) -> FieldValue:
        try:
            return self.tokens.decode(raw)
        except ValueError:
            return self.number.decode(raw)

    def parse_text(self, text: str) -> FieldValue:
        return text if self.tokens.lookup(text) is not None else self.number.parse_text(text)

    def is_idempotent(self, raw: bytes) -> bool:
        return self.tokens.is_idempotent(raw)

    def neutral(self) -> FieldValue:
        return self.number.neutral()

    def describe(self) -> CodecDescription:
        d = super().describe()
        d["tokens"] = self.tokens.describe()["values"]
        d["number"] = self.number.describe()
        return d


def _numeric(text: str) -> bool:
    try:
        float(text)
    except ValueError:
        return False
    return True


__all__ = ["KEEP_NAMES", "ON_OFF", "Enum", "EnumValue", "OneOf", "enum"]
