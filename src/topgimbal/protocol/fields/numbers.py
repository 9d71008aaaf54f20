"""Number codecs: hex and decimal text, decimal floats, packed binary, TOPOTEK's bitrate."""

from __future__ import annotations

from binascii import Error as BinasciiError
from binascii import unhexlify
from dataclasses import dataclass, field
from typing import ClassVar

from ...errors import FieldValueError
from .base import Codec, clamp_neutral, decimals_of, fmt, in_range, to_number

_HEX_DIGITS = b"0123456789ABCDEFabcdef"


def _range_text(lo: float | None, hi: float | None, unit: str, scale: float = 1) -> str:
    s = f"{fmt(lo)}..{fmt(hi)}"
    if unit:
        s += f" {unit}"
    if scale != 1:
        s += f" in steps of {fmt(scale)}"
    return s


@dataclass(frozen=True)
class HexInt(Codec):
    """An integer written as `width` hex characters (two's complement when signed), times `scale`.

    `none_tokens` are wire spellings that mean "no value" (e.g. `NNNNN` = no SD card)."""

    width: int
    signed: bool = False
    scale: float = 1
    unit: str = ""
    min: float | None = None
    max: float | None = None
    none_tokens: tuple[bytes, ...] = ()
    kind: ClassVar[str] = "number"
    # Derived once (decode is on the hot path); declared so that types and equality stay exact.
    _raw_lo: int = field(init=False, repr=False, compare=False, default=0)
    _raw_hi: int = field(init=False, repr=False, compare=False, default=0)
    _dec: int = field(init=False, repr=False, compare=False, default=0)
    _div: int = field(init=False, repr=False, compare=False, default=0)
    _half: int = field(init=False, repr=False, compare=False, default=0)
    _full: int = field(init=False, repr=False, compare=False, default=0)
    _decode_plan: tuple[int, bool, bool, int, float, int] = field(
        init=False, repr=False, compare=False, default=(0, True, False, 0, 1.0, 0)
    )

    def __post_init__(self) -> None:
        bits = 4 * self.width
        lo, hi = (-(1 << (bits - 1)), (1 << (bits - 1)) - 1) if self.signed else (0, (1 << bits) - 1)
        dec = decimals_of(self.scale)
        inv = 1 / self.scale
        # Dividing by an exact integer (100 for 0.01) gives the correctly rounded float directly,
        # which is both exact and cheaper than round(v * scale, n) on the decode hot path.
        div = round(inv) if self.scale < 1 and abs(inv - round(inv)) < 1e-9 else 0
        set_ = object.__setattr__
        set_(self, "_raw_lo", lo)
        set_(self, "_raw_hi", hi)
        set_(self, "_dec", dec)
        set_(self, "_div", div)
        set_(self, "_half", 1 << (bits - 1))
        set_(self, "_full", 1 << bits)
        if self.min is None:
            set_(self, "min", round(lo * self.scale, dec))
        if self.max is None:
            set_(self, "max", round(hi * self.scale, dec))
        # decode's constants in one tuple (one attribute load on the hot path); an even width is
        # whole bytes: unhexlify validates and converts, from_bytes takes the two's complement
        set_(self, "_decode_plan", (self.width, self.width % 2 == 0, self.signed, div, self.scale, dec))

    def allowed(self) -> str:
        return _range_text(self.min, self.max, self.unit, self.scale) + (" or null" if self.none_tokens else "")

    def encode(self, value: object, name: str = "value") -> bytes:
        if value is None and self.none_tokens:
            return self.none_tokens[0]
        v = to_number(value, name, self)
        lo = self.min if self.min is not None else self._raw_lo * self.scale
        hi = self.max if self.max is not None else self._raw_hi * self.scale
        if not in_range(v, lo, hi):
            raise FieldValueError(name, value, self.allowed())
        raw = round(v / self.scale)
        if not self._raw_lo <= raw <= self._raw_hi:
            raise FieldValueError(name, value, self.allowed())
        if raw < 0:
            raw += self._full
        return b"%0*X" % (self.width, raw)

    def decode(self, raw: bytes) -> int | float | None:
        width, whole_bytes, signed, div, scale, dec = self._decode_plan
        if self.none_tokens and raw in self.none_tokens:
            return None
        if len(raw) != width:
            raise ValueError(f"{raw!r} is not {width} hex digits")
        if whole_bytes:
            try:
                v = int.from_bytes(unhexlify(raw), "big", signed=signed)
            except (BinasciiError, TypeError):
                raise ValueError(f"{raw!r} is not {width} hex digits") from None
        else:
            if raw.translate(None, _HEX_DIGITS):
                raise ValueError(f"{raw!r} is not {width} hex digits")
            v = int(raw, 16)
            if signed and v >= self._half:
                v -= self._full
        if div:
            return v / div
        if scale == 1:
            return v
        return round(v * scale, dec)

    def packed_plan(self) -> tuple[str, int, float, int] | None:
        """(struct letter, divisor, scale, decimals) when `decode` is exactly "unhexlify, unpack
        big-endian, then divide by the divisor (or round(v * scale, decimals), or v when both are
        neutral)": whole bytes of a width struct has, no none tokens. A form decodes a run of such
        fields with one unhexlify and one unpack (Form._build_decoder)."""
        letter = {2: "b", 4: "h", 8: "i", 16: "q"}.get(self.width)
        if letter is None or self.none_tokens:
            return None
        return (letter if self.signed else letter.upper(), self._div, self.scale, self._dec)

    def parse_text(self, text: str) -> int | float | None:
        if self.none_tokens and text.lower() in ("null", "none"):
            return None
        return float(text) if self.scale != 1 or "." in text else int(text, 0)

    def neutral(self) -> int | float:
        return clamp_neutral(self.min, self.max) if self.scale != 1 else int(clamp_neutral(self.min, self.max))


@dataclass(frozen=True)
class DecInt(Codec):
    """A number written as `width` decimal digits (zero padded), times `scale` (MUL: 0123 = 12.3x)."""

    width: int
    scale: float = 1
    unit: str = ""
    min: float = 0
    max: float | None = None
    kind: ClassVar[str] = "number"
    _dec: int = field(init=False, repr=False, compare=False, default=0)

    def __post_init__(self) -> None:
        object.__setattr__(self, "_dec", decimals_of(self.scale))
        if self.max is None:
            object.__setattr__(self, "max", round((10**self.width - 1) * self.scale, self._dec))
        if self.min < 0:
            raise ValueError("DecInt has no sign character: min must be >= 0")

    def allowed(self) -> str:
        return _range_text(self.min, self.max, self.unit, self.scale)

    def encode(self, value: object, name: str = "value") -> bytes:
        v = to_number(value, name, self)
        hi = self.max if self.max is not None else (10**self.width - 1) * self.scale
        if not in_range(v, self.min, hi):  # first: a huge float would overflow round()
            raise FieldValueError(name, value, self.allowed())
        raw = round(v / self.scale)
        if not 0 <= raw < 10**self.width:
            raise FieldValueError(name, value, self.allowed())
        return b"%0*d" % (self.width, raw)

    def decode(self, raw: bytes) -> int | float:
        if len(raw) != self.width or not raw.isdigit():
            raise ValueError(f"{raw!r} is not {self.width} decimal digits")
        v = int(raw)
        return v if self.scale == 1 else round(v * self.scale, self._dec)

    def parse_text(self, text: str) -> int | float:
        return float(text) if self.scale != 1 or "." in text else int(text)

    def neutral(self) -> int | float:
        v = clamp_neutral(self.min, self.max)
        return v if self.scale != 1 else int(v)


@dataclass(frozen=True)
class DecFloat(Codec):
    """A decimal number with a point (`%0W.Df`): ALT `-0012.3`, AZI `045.0`, LRF `00123.4`.

    Variable width when `width` is None: encoded zero-padded to `pad` characters, decoded from any
    spelling float() reads of 1..15 characters. A value that rounds to zero is sent without a sign."""

    width: int | None = None
    decimals: int = 1
    unit: str = ""
    min: float = 0
    max: float = 0
    none_tokens: tuple[bytes, ...] = ()
    pad: int = 0
    kind: ClassVar[str] = "number"

    @property
    def max_width(self) -> int:
        return self.width if self.width is not None else 15

    @property
    def min_width(self) -> int:
        return self.width if self.width is not None else 1

    @property
    def scale(self) -> float:
        return 10.0**-self.decimals

    def allowed(self) -> str:
        s = f"{self.min:.{self.decimals}f}..{self.max:.{self.decimals}f}"
        if self.unit:
            s += f" {self.unit}"
        if self.none_tokens:
            s += " or null (" + "/".join(t.decode() for t in self.none_tokens) + ")"
        return s

    def encode(self, value: object, name: str = "value") -> bytes:
        if value is None and self.none_tokens:
            return self.none_tokens[0]
        v = to_number(value, name, self)
        if not in_range(v, self.min, self.max):
            raise FieldValueError(name, value, self.allowed())
        v = round(v, self.decimals) + 0.0
        if v == 0:
            v = 0.0  # never "-0.0"
        out = f"{v:0{self.pad if self.width is None else self.width}.{self.decimals}f}".encode()
        if not self.min_width <= len(out) <= self.max_width:
            raise FieldValueError(name, value, self.allowed())
        return out

    def decode(self, raw: bytes) -> float | None:
        if raw.strip() in self.none_tokens or raw[:3] in self.none_tokens:
            return None
        if self.width is not None and len(raw) != self.width:
            raise ValueError(f"{raw!r} is not {self.width} characters")
        text = raw.decode("ascii").strip()
        if not text or text.lower().lstrip("+-") in ("nan", "inf", "infinity") or "_" in text:
            raise ValueError(f"{raw!r} is not a number")
        return round(float(text), self.decimals) + 0.0

    def parse_text(self, text: str) -> float | None:
        if self.none_tokens and text.lower() in ("null", "none"):
            return None
        return float(text)

    def neutral(self) -> float:
        return clamp_neutral(self.min, self.max)


@dataclass(frozen=True)
class BinInt(Codec):
    """A packed binary integer (C struct member) of `width` bytes, times `scale`."""

    width: int
    signed: bool = True
    byteorder: str = "little"
    scale: float = 1
    unit: str = ""
    min: float | None = None
    max: float | None = None
    kind: ClassVar[str] = "number"
    _dec: int = field(init=False, repr=False, compare=False, default=0)
    _raw_lo: int = field(init=False, repr=False, compare=False, default=0)
    _raw_hi: int = field(init=False, repr=False, compare=False, default=0)

    def __post_init__(self) -> None:
        if self.byteorder not in ("little", "big"):
            raise ValueError(f"byteorder must be 'little' or 'big', not {self.byteorder!r}")
        bits = 8 * self.width
        lo, hi = (-(1 << (bits - 1)), (1 << (bits - 1)) - 1) if self.signed else (0, (1 << bits) - 1)
        dec = decimals_of(self.scale)
        object.__setattr__(self, "_dec", dec)
        object.__setattr__(self, "_raw_lo", lo)
        object.__setattr__(self, "_raw_hi", hi)
        if self.min is None:
            object.__setattr__(self, "min", round(lo * self.scale, dec))
        if self.max is None:
            object.__setattr__(self, "max", round(hi * self.scale, dec))

    def allowed(self) -> str:
        return _range_text(self.min, self.max, self.unit)

    def encode(self, value: object, name: str = "value") -> bytes:
        v = to_number(value, name, self)
        lo = self.min if self.min is not None else self._raw_lo * self.scale
        hi = self.max if self.max is not None else self._raw_hi * self.scale
        if not in_range(v, lo, hi):  # first: a huge float would overflow round()
            raise FieldValueError(name, value, self.allowed())
        raw = round(v / self.scale)
        if not self._raw_lo <= raw <= self._raw_hi:
            raise FieldValueError(name, value, self.allowed())
        return raw.to_bytes(self.width, "little" if self.byteorder == "little" else "big", signed=self.signed)

    def decode(self, raw: bytes) -> int | float:
        if len(raw) != self.width:
            raise ValueError(f"{len(raw)} bytes where {self.width} are needed")
        v = int.from_bytes(raw, "little" if self.byteorder == "little" else "big", signed=self.signed)
        return v if self.scale == 1 else round(v * self.scale, self._dec)

    def parse_text(self, text: str) -> int | float:
        return float(text) if self.scale != 1 or "." in text else int(text, 0)

    def neutral(self) -> int | float:
        v = clamp_neutral(self.min, self.max)
        return v if self.scale != 1 else int(v)


@dataclass(frozen=True)
class Bitrate(Codec):
    """TOPOTEK BIT: `0M0000` (M = 1..8 Mbps) or `Kddddd` (kbps, 50..99999). User value: kbps.

    Variable width: answers are also seen as `0M` or `M` (errata E23); encoding always gives 6
    characters."""

    unit: str = "kbps"
    width: int | None = None
    min: int = 50
    max: int = 99999
    scale: int = 1
    kind: ClassVar[str] = "number"

    @property
    def min_width(self) -> int:
        return 1

    @property
    def max_width(self) -> int:
        return 6

    def allowed(self) -> str:
        return f"{self.min}..{self.max} kbps, whole numbers (1000..8000 in whole Mbps use the Mbps form)"

    def encode(self, value: object, name: str = "value") -> bytes:
        v = to_number(value, name, self)
        if not v.is_integer() or not self.min <= v <= self.max:
            raise FieldValueError(name, value, self.allowed())
        kbps = int(v)
        if kbps % 1000 == 0 and 1 <= kbps // 1000 <= 8:
            return b"0%d0000" % (kbps // 1000)
        return b"K%05d" % kbps

    def decode(self, raw: bytes) -> int:
        if len(raw) == 6 and raw[:1] in (b"K", b"k") and raw[1:].isdigit():
            return int(raw[1:])
        if len(raw) in (2, 6) and raw[:1] == b"0" and raw[1:2].isdigit() and (len(raw) == 2 or raw[2:].isdigit()):
            return int(raw[1:2]) * 1000
        if len(raw) == 1 and raw.isdigit():
            return int(raw) * 1000
        raise ValueError(f"{raw!r} is not 0M0000, Kddddd, 0M or a Mbps digit")

    def parse_text(self, text: str) -> int:
        return int(text)

    def neutral(self) -> int:
        return self.min


__all__ = ["BinInt", "Bitrate", "DecFloat", "DecInt", "HexInt"]
