"""Field codecs: how one field's value in user units becomes bytes of a frame's data, and back.

Each codec carries its metadata as data (width, unit, range, enum table, description of what is
allowed) so that the encoder, decoder, simulator, CLI, console and generated docs all read the same
facts. Codecs are immutable and pure; `encode` raises `FieldValueError` naming the field, the value
and what is allowed; `decode` raises `ValueError` on bytes that do not fit.
"""

from __future__ import annotations

import ipaddress
import math
from collections.abc import Mapping
from dataclasses import dataclass, field
from datetime import datetime
from typing import Any

from ..errors import FieldValueError


def _decimals(scale: float) -> int:
    if scale >= 1 and float(scale).is_integer():
        return 0
    return max(0, -math.floor(math.log10(scale) + 1e-9)) if scale < 1 else 0


def _num(value: Any, name: str, codec: Codec) -> float:
    """`value` as a float, or FieldValueError naming what `codec` allows (built only on error)."""
    if isinstance(value, bool):
        raise FieldValueError(name, value, codec.allowed())
    if isinstance(value, str):
        try:
            value = float(value)
        except ValueError:
            raise FieldValueError(name, value, codec.allowed()) from None
    if not isinstance(value, (int, float)) or math.isnan(value) or math.isinf(value):
        raise FieldValueError(name, value, codec.allowed())
    return float(value)


def _fmt(v: float) -> str:
    return f"{v:g}"


class Codec:
    """Base class. `width` is the fixed number of data bytes, or None for a variable-width codec
    that takes the rest of the data (`min_width`..`max_width`)."""

    kind: str = "raw"
    width: int | None = None
    unit: str = ""

    @property
    def min_width(self) -> int:
        return self.width if self.width is not None else 0

    @property
    def max_width(self) -> int:
        return self.width if self.width is not None else 0xFF

    def encode(self, value: Any, name: str = "value") -> bytes:
        raise NotImplementedError

    def decode(self, raw: bytes) -> Any:
        raise NotImplementedError

    def allowed(self) -> str:
        """What values `encode` accepts, in words (used by errors, CLI help and docs)."""
        raise NotImplementedError

    def parse_text(self, text: str) -> Any:
        """A value from command-line text."""
        return text

    def to_json(self, value: Any) -> Any:
        return value

    def describe(self) -> dict[str, Any]:
        """Metadata as JSON-able data; number codecs add `min`, `max` and `step` (user units)."""
        d: dict[str, Any] = {"kind": self.kind, "width": self.width, "unit": self.unit, "allowed": self.allowed()}
        if self.kind == "number":
            for key in ("min", "max"):
                v = getattr(self, key, None)
                if isinstance(v, (int, float)) and not isinstance(v, bool):
                    d[key] = v
            scale, decimals = getattr(self, "scale", None), getattr(self, "decimals", None)
            if isinstance(scale, (int, float)) and scale:
                d["step"] = scale
            elif isinstance(decimals, int):
                d["step"] = 10.0**-decimals
        return d


# -- numbers ---------------------------------------------------------------------------------------


@dataclass(frozen=True)
class HexInt(Codec):
    """An integer written as `width` hex characters (two's complement when signed), times `scale`.

    `none_tokens` are wire spellings that mean "no value" (e.g. `NNNNN` = no SD card)."""

    width: int  # type: ignore[misc]
    signed: bool = False
    scale: float = 1
    unit: str = ""
    min: float | None = None
    max: float | None = None
    none_tokens: tuple[bytes, ...] = ()
    kind: str = "number"

    def __post_init__(self) -> None:
        bits = 4 * self.width
        lo_raw, hi_raw = (-(1 << (bits - 1)), (1 << (bits - 1)) - 1) if self.signed else (0, (1 << bits) - 1)
        object.__setattr__(self, "_bits", bits)
        object.__setattr__(self, "_dec", _decimals(self.scale))
        # Dividing by an exact integer (100 for 0.01) gives the correctly rounded float directly,
        # which is both exact and cheaper than round(v * scale, n) on the decode hot path.
        inv = 1 / self.scale
        object.__setattr__(self, "_div", round(inv) if self.scale < 1 and abs(inv - round(inv)) < 1e-9 else 0)
        object.__setattr__(self, "_half", 1 << (bits - 1))
        object.__setattr__(self, "_full", 1 << bits)
        if self.min is None:
            object.__setattr__(self, "min", round(lo_raw * self.scale, _decimals(self.scale)))
        if self.max is None:
            object.__setattr__(self, "max", round(hi_raw * self.scale, _decimals(self.scale)))

    def allowed(self) -> str:
        s = f"{_fmt(self.min)}..{_fmt(self.max)}"  # type: ignore[arg-type]
        if self.unit:
            s += f" {self.unit}"
        if self.scale != 1:
            s += f" in steps of {_fmt(self.scale)}"
        if self.none_tokens:
            s += " or null"
        return s

    def encode(self, value: Any, name: str = "value") -> bytes:
        if value is None and self.none_tokens:
            return self.none_tokens[0]
        v = _num(value, name, self)
        if not (self.min - 1e-9 <= v <= self.max + 1e-9):  # type: ignore[operator]
            raise FieldValueError(name, value, self.allowed())
        raw = round(v / self.scale)
        if raw < 0:
            raw += 1 << self._bits  # type: ignore[attr-defined]
        return b"%0*X" % (self.width, raw)

    def decode(self, raw: bytes) -> Any:
        if raw in self.none_tokens:
            return None
        if len(raw) != self.width or raw.translate(None, b"0123456789ABCDEFabcdef"):
            raise ValueError(f"{raw!r} is not {self.width} hex digits")
        v = int(raw, 16)
        if self.signed and v >= self._half:  # type: ignore[attr-defined]
            v -= self._full  # type: ignore[attr-defined]
        if self._div:  # type: ignore[attr-defined]
            return v / self._div  # type: ignore[attr-defined]
        if self.scale == 1:
            return v
        return round(v * self.scale, self._dec)  # type: ignore[attr-defined]

    def parse_text(self, text: str) -> Any:
        if self.none_tokens and text.lower() in ("null", "none"):
            return None
        return float(text) if self.scale != 1 or "." in text else int(text, 0)


@dataclass(frozen=True)
class DecInt(Codec):
    """A number written as `width` decimal digits (zero padded), times `scale` (MUL: 0123 = 12.3x)."""

    width: int  # type: ignore[misc]
    scale: float = 1
    unit: str = ""
    min: float = 0
    max: float | None = None
    kind: str = "number"

    def __post_init__(self) -> None:
        if self.max is None:
            object.__setattr__(self, "max", round((10**self.width - 1) * self.scale, _decimals(self.scale)))

    def allowed(self) -> str:
        s = f"{_fmt(self.min)}..{_fmt(self.max)}"  # type: ignore[arg-type]
        if self.unit:
            s += f" {self.unit}"
        if self.scale != 1:
            s += f" in steps of {_fmt(self.scale)}"
        return s

    def encode(self, value: Any, name: str = "value") -> bytes:
        v = _num(value, name, self)
        if not (self.min - 1e-9 <= v <= self.max + 1e-9):  # type: ignore[operator]
            raise FieldValueError(name, value, self.allowed())
        return b"%0*d" % (self.width, round(v / self.scale))

    def decode(self, raw: bytes) -> Any:
        if len(raw) != self.width or not raw.isdigit():
            raise ValueError(f"{raw!r} is not {self.width} decimal digits")
        v = int(raw)
        return v if self.scale == 1 else round(v * self.scale, _decimals(self.scale))

    def parse_text(self, text: str) -> Any:
        return float(text) if self.scale != 1 or "." in text else int(text)


@dataclass(frozen=True)
class DecFloat(Codec):
    """A decimal number with a point (`%0W.Df`): ALT `-0012.3`, AZI `045.0`, LRF `00123.4`.

    Variable width when `width` is None (decoding accepts any spelling float() reads)."""

    width: int | None = None
    decimals: int = 1
    unit: str = ""
    min: float = 0
    max: float = 0
    none_tokens: tuple[bytes, ...] = ()
    pad: int = 0  # variable-width fields: encode zero-padded to this many characters
    kind: str = "number"

    @property
    def max_width(self) -> int:
        return self.width if self.width is not None else 15

    @property
    def min_width(self) -> int:
        return self.width if self.width is not None else 1

    def allowed(self) -> str:
        s = f"{self.min:.{self.decimals}f}..{self.max:.{self.decimals}f}"
        if self.unit:
            s += f" {self.unit}"
        if self.none_tokens:
            s += " or null (" + "/".join(t.decode() for t in self.none_tokens) + ")"
        return s

    def encode(self, value: Any, name: str = "value") -> bytes:
        if value is None and self.none_tokens:
            return self.none_tokens[0]
        v = _num(value, name, self)
        if not (self.min - 1e-9 <= v <= self.max + 1e-9):
            raise FieldValueError(name, value, self.allowed())
        if self.width is None:
            return f"{v:0{self.pad}.{self.decimals}f}".encode()
        return f"{v:0{self.width}.{self.decimals}f}".encode()

    def decode(self, raw: bytes) -> Any:
        if raw.strip() in self.none_tokens or raw[:3] in self.none_tokens:
            return None
        if self.width is not None and len(raw) != self.width:
            raise ValueError(f"{raw!r} is not {self.width} characters")
        text = raw.decode("ascii").strip()
        if not text or text.lower() in ("nan", "inf", "-inf", "+inf", "infinity"):
            raise ValueError(f"{raw!r} is not a number")
        return round(float(text), self.decimals)

    def parse_text(self, text: str) -> Any:
        if self.none_tokens and text.lower() in ("null", "none"):
            return None
        return float(text)


@dataclass(frozen=True)
class BinInt(Codec):
    """A packed binary integer (C struct member) of `width` bytes, times `scale`."""

    width: int  # type: ignore[misc]
    signed: bool = True
    byteorder: str = "little"
    scale: float = 1
    unit: str = ""
    min: float | None = None
    max: float | None = None
    kind: str = "number"

    def __post_init__(self) -> None:
        bits = 8 * self.width
        lo, hi = (-(1 << (bits - 1)), (1 << (bits - 1)) - 1) if self.signed else (0, (1 << bits) - 1)
        if self.min is None:
            object.__setattr__(self, "min", round(lo * self.scale, _decimals(self.scale)))
        if self.max is None:
            object.__setattr__(self, "max", round(hi * self.scale, _decimals(self.scale)))

    def allowed(self) -> str:
        s = f"{_fmt(self.min)}..{_fmt(self.max)}"  # type: ignore[arg-type]
        return s + (f" {self.unit}" if self.unit else "")

    def encode(self, value: Any, name: str = "value") -> bytes:
        v = _num(value, name, self)
        if not (self.min - 1e-9 <= v <= self.max + 1e-9):  # type: ignore[operator]
            raise FieldValueError(name, value, self.allowed())
        return round(v / self.scale).to_bytes(self.width, self.byteorder, signed=self.signed)  # type: ignore[arg-type]

    def decode(self, raw: bytes) -> Any:
        if len(raw) != self.width:
            raise ValueError(f"{len(raw)} bytes where {self.width} are needed")
        v = int.from_bytes(raw, self.byteorder, signed=self.signed)  # type: ignore[arg-type]
        return v if self.scale == 1 else round(v * self.scale, _decimals(self.scale))

    def parse_text(self, text: str) -> Any:
        return float(text) if self.scale != 1 or "." in text else int(text, 0)


# -- enumerations ----------------------------------------------------------------------------------


@dataclass(frozen=True)
class EnumValue:
    raw: str
    name: str
    label: str = ""
    idempotent: bool = True  # False for toggles and relative steps: never retried


@dataclass(frozen=True)
class Enum(Codec):
    """A value from a table of wire spellings, named in user space (`follow`, `white_hot`)."""

    width: int  # type: ignore[misc]
    values: tuple[EnumValue, ...] = ()
    kind: str = "enum"
    _by_raw: Mapping[bytes, EnumValue] = field(default_factory=dict, repr=False, compare=False)
    _by_name: Mapping[str, EnumValue] = field(default_factory=dict, repr=False, compare=False)

    def __post_init__(self) -> None:
        by_raw: dict[bytes, EnumValue] = {}
        by_name: dict[str, EnumValue] = {}
        for v in self.values:
            if len(v.raw) != self.width:
                raise ValueError(f"enum spelling {v.raw!r} is not {self.width} characters")
            by_raw[v.raw.encode("latin-1")] = v
            by_raw.setdefault(v.raw.lower().encode("latin-1"), v)  # some firmware spells hex in lower case
            by_name[v.name] = v
        object.__setattr__(self, "_by_raw", by_raw)
        object.__setattr__(self, "_by_name", by_name)

    def allowed(self) -> str:
        return "one of " + ", ".join(f"{v.name} ({v.raw})" for v in self.values)

    def lookup(self, value: Any) -> EnumValue | None:
        if isinstance(value, EnumValue):
            return value if value in self.values else None
        if isinstance(value, bool):
            value = int(value)
        if isinstance(value, str):
            v = self._by_name.get(value) or self._by_name.get(value.lower().replace("-", "_"))
            if v is None:
                v = self._by_raw.get(value.encode("latin-1", "replace"))
            return v
        if isinstance(value, int) and value >= 0:
            return self._by_raw.get(b"%0*X" % (self.width, value))
        return None

    def encode(self, value: Any, name: str = "value") -> bytes:
        v = self.lookup(value)
        if v is None:
            raise FieldValueError(name, value, self.allowed())
        return v.raw.encode("latin-1")

    def decode(self, raw: bytes) -> Any:
        v = self._by_raw.get(raw)
        if v is None:
            raise ValueError(f"{raw!r} is not in the table ({', '.join(x.raw for x in self.values)})")
        return v.name

    def is_idempotent(self, raw: bytes) -> bool:
        v = self._by_raw.get(raw)
        return True if v is None else v.idempotent

    def describe(self) -> dict[str, Any]:
        d = super().describe()
        d["values"] = [
            {"raw": v.raw, "name": v.name, "label": v.label, "idempotent": v.idempotent} for v in self.values
        ]
        return d


def enum(width: int, table: Mapping[str, str | tuple[str, str]], *, toggles: str | tuple[str, ...] = ()) -> Enum:
    """Shorthand: `enum(2, {"00": "stop", "01": ("up", "Nudge up")}, toggles=("08",))`."""
    if isinstance(toggles, str):
        toggles = (toggles,)
    vals = []
    for raw, spec in table.items():
        name, label = (spec, spec.replace("_", " ")) if isinstance(spec, str) else spec
        vals.append(EnumValue(raw, name, label, raw not in toggles))
    return Enum(width, tuple(vals))


ON_OFF = enum(2, {"00": "off", "01": "on"})


@dataclass(frozen=True)
class OneOf(Codec):
    """Either a token from an enum or a number (TOPOTEK DZM: `0A` = step in, `25` = 2.5x)."""

    tokens: Enum
    number: Codec
    kind: str = "enum_or_number"

    @property
    def width(self) -> int | None:  # type: ignore[override]
        return self.tokens.width

    def allowed(self) -> str:
        return f"{self.number.allowed()}, or {self.tokens.allowed()}"

    def encode(self, value: Any, name: str = "value") -> bytes:
        if isinstance(value, str) and self.tokens.lookup(value) is not None:
            try:
                float(value)
            except ValueError:
                return self.tokens.encode(value, name)
        try:
            return self.number.encode(value, name)
        except FieldValueError:
            raise FieldValueError(name, value, self.allowed()) from None

    def decode(self, raw: bytes) -> Any:
        try:
            return self.tokens.decode(raw)
        except ValueError:
            return self.number.decode(raw)

    def parse_text(self, text: str) -> Any:
        return text if self.tokens.lookup(text) is not None else self.number.parse_text(text)

    def is_idempotent(self, raw: bytes) -> bool:
        return self.tokens.is_idempotent(raw)

    def describe(self) -> dict[str, Any]:
        d = super().describe()
        d["tokens"] = self.tokens.describe()["values"]
        d["number"] = self.number.describe()
        return d


# -- text ------------------------------------------------------------------------------------------


@dataclass(frozen=True)
class Text(Codec):
    """Printable ASCII text of `min_len`..`max_len` characters (versions, model names)."""

    min_len: int = 1
    max_len: int = 15
    kind: str = "text"

    @property
    def min_width(self) -> int:
        return self.min_len

    @property
    def max_width(self) -> int:
        return self.max_len

    def allowed(self) -> str:
        return f"printable ASCII text of {self.min_len}..{self.max_len} characters"

    def encode(self, value: Any, name: str = "value") -> bytes:
        if not isinstance(value, str) or not value.isascii() or not value.isprintable():
            raise FieldValueError(name, value, self.allowed())
        if not self.min_len <= len(value) <= self.max_len:
            raise FieldValueError(name, value, self.allowed())
        return value.encode("ascii")

    def decode(self, raw: bytes) -> Any:
        if not self.min_len <= len(raw) <= self.max_len:
            raise ValueError(f"{len(raw)} characters, expected {self.min_len}..{self.max_len}")
        return raw.decode("latin-1")


@dataclass(frozen=True)
class IPv4Text(Codec):
    """A dotted IPv4 address as text (`192.168.31.22`)."""

    kind: str = "ipv4"

    @property
    def min_width(self) -> int:
        return 7

    @property
    def max_width(self) -> int:
        return 15

    def allowed(self) -> str:
        return "a dotted IPv4 address (a.b.c.d, each 0..255)"

    def encode(self, value: Any, name: str = "value") -> bytes:
        try:
            return str(ipaddress.IPv4Address(str(value))).encode("ascii")
        except ValueError:
            raise FieldValueError(name, value, self.allowed()) from None

    def decode(self, raw: bytes) -> Any:
        return str(ipaddress.IPv4Address(raw.decode("ascii")))


@dataclass(frozen=True)
class RawData(Codec):
    """Bytes whose layout the documents do not give; shown and entered as hex."""

    width: int | None = None
    kind: str = "raw"

    @property
    def min_width(self) -> int:
        return self.width if self.width is not None else 0

    def allowed(self) -> str:
        n = f"{self.width} bytes" if self.width is not None else "0..255 bytes"
        return f"{n} given as a hex string"

    def encode(self, value: Any, name: str = "value") -> bytes:
        try:
            data = bytes(value) if isinstance(value, (bytes, bytearray)) else bytes.fromhex(str(value))
        except ValueError:
            raise FieldValueError(name, value, self.allowed()) from None
        if self.width is not None and len(data) != self.width:
            raise FieldValueError(name, value, self.allowed())
        return data

    def decode(self, raw: bytes) -> Any:
        if self.width is not None and len(raw) != self.width:
            raise ValueError(f"{len(raw)} bytes where {self.width} are needed")
        return raw.hex()


@dataclass(frozen=True)
class Literal(Codec):
    """Fixed data (the error frame's `!!`); decodes to itself."""

    text: str = "!!"
    kind: str = "literal"

    @property
    def width(self) -> int:  # type: ignore[override]
        return len(self.text)

    def allowed(self) -> str:
        return f"exactly {self.text!r}"

    def encode(self, value: Any, name: str = "value") -> bytes:
        if value not in (None, self.text):
            raise FieldValueError(name, value, self.allowed())
        return self.text.encode("latin-1")

    def decode(self, raw: bytes) -> Any:
        if raw != self.text.encode("latin-1"):
            raise ValueError(f"{raw!r} is not {self.text!r}")
        return self.text


# -- geography and time ----------------------------------------------------------------------------


@dataclass(frozen=True)
class GeoDM(Codec):
    """NMEA degrees-and-minutes with hemisphere: `N3030.1234` (lat) / `E11400.5678` (lon).

    User value: signed decimal degrees (south and west negative)."""

    axis: str = "lat"  # "lat" or "lon"
    unit: str = "deg"
    kind: str = "coordinate"

    @property
    def width(self) -> int:  # type: ignore[override]
        return 10 if self.axis == "lat" else 11

    def allowed(self) -> str:
        lim = 90 if self.axis == "lat" else 180
        return f"-{lim}..{lim} deg (sent as {'N/S ddmm.mmmm' if self.axis == 'lat' else 'E/W dddmm.mmmm'})"

    def encode(self, value: Any, name: str = "value") -> bytes:
        lim = 90 if self.axis == "lat" else 180
        v = _num(value, name, self)
        if not -lim <= v <= lim:
            raise FieldValueError(name, value, self.allowed())
        hemi = ("N" if v >= 0 else "S") if self.axis == "lat" else ("E" if v >= 0 else "W")
        a = abs(v)
        deg = int(a)
        minutes = round((a - deg) * 60, 4)
        if minutes >= 60:
            deg, minutes = deg + 1, 0.0
        dd = 2 if self.axis == "lat" else 3
        return f"{hemi}{deg:0{dd}d}{minutes:07.4f}".encode()

    def decode(self, raw: bytes) -> Any:
        text = raw.decode("ascii").replace(" ", "")
        hemi, body = text[:1].upper(), text[1:]
        signs = {"N": 1, "S": -1} if self.axis == "lat" else {"E": 1, "W": -1}
        if hemi not in signs or "." not in body:
            raise ValueError(f"{raw!r} is not {'N/S ddmm.mmmm' if self.axis == 'lat' else 'E/W dddmm.mmmm'}")
        dot = body.index(".")
        if dot != (4 if self.axis == "lat" else 5) or not body.replace(".", "", 1).isdigit():
            raise ValueError(f"{raw!r} is not {'N/S ddmm.mmmm' if self.axis == 'lat' else 'E/W dddmm.mmmm'}")
        deg, minutes = int(body[: dot - 2]), float(body[dot - 2 :])
        if minutes >= 60:
            raise ValueError(f"{raw!r}: minutes {minutes} >= 60")
        return round(signs[hemi] * (deg + minutes / 60), 7)


@dataclass(frozen=True)
class GeoDeg(Codec):
    """Decimal degrees with hemisphere (TOPOTEK §8.7 target solution): `N22.123456`, `E113.123456`."""

    axis: str = "lat"
    unit: str = "deg"
    kind: str = "coordinate"

    @property
    def width(self) -> int:  # type: ignore[override]
        return 10 if self.axis == "lat" else 11

    def allowed(self) -> str:
        lim = 90 if self.axis == "lat" else 180
        return f"-{lim}..{lim} deg (sent as {'N/S dd.dddddd' if self.axis == 'lat' else 'E/W ddd.dddddd'})"

    def encode(self, value: Any, name: str = "value") -> bytes:
        lim = 90 if self.axis == "lat" else 180
        v = _num(value, name, self)
        if not -lim <= v <= lim:
            raise FieldValueError(name, value, self.allowed())
        hemi = ("N" if v >= 0 else "S") if self.axis == "lat" else ("E" if v >= 0 else "W")
        return f"{hemi}{abs(v):0{self.width - 1}.6f}".encode()

    def decode(self, raw: bytes) -> Any:
        text = raw.decode("ascii").replace(" ", "")
        signs = {"N": 1, "S": -1} if self.axis == "lat" else {"E": 1, "W": -1}
        body = text[1:]
        if text[:1].upper() not in signs or "." not in body or body.index(".") != (2 if self.axis == "lat" else 3):
            raise ValueError(f"{raw!r} is not {'N/S dd.dddddd' if self.axis == 'lat' else 'E/W ddd.dddddd'}")
        return round(signs[text[:1].upper()] * float(text[1:]), 7)


@dataclass(frozen=True)
class Timestamp(Codec):
    """A date and time as fixed decimal text. `layout` is a strftime pattern; `%f2` means
    hundredths of a second (SkyDroid TIM `hhmmss.ssDDMMYY`). User value: `datetime` (naive)."""

    layout: str = "%Y%m%d%H%M%S"
    kind: str = "datetime"

    @property
    def width(self) -> int:  # type: ignore[override]
        return len(datetime(2000, 1, 1).strftime(self.layout.replace("%f2", "00")))

    def allowed(self) -> str:
        return f"a date and time (ISO 8601 text or datetime), sent as {self.layout.replace('%f2', 'ss')}"

    def encode(self, value: Any, name: str = "value") -> bytes:
        if isinstance(value, str):
            try:
                value = datetime.fromisoformat(value)
            except ValueError:
                raise FieldValueError(name, value, self.allowed()) from None
        if not isinstance(value, datetime):
            raise FieldValueError(name, value, self.allowed())
        if "%y" in self.layout and not 2000 <= value.year <= 2099:
            raise FieldValueError(name, value, self.allowed() + ", years 2000..2099")
        hundredths = f"{value.microsecond // 10000:02d}"
        return value.strftime(self.layout.replace("%f2", hundredths)).encode("ascii")

    def decode(self, raw: bytes) -> Any:
        text = raw.decode("ascii")
        if len(text) != self.width:
            raise ValueError(f"{raw!r} is not {self.width} characters")
        if "%f2" in self.layout:
            at = self.layout.index("%f2")
            pre = len(datetime(2000, 1, 1).strftime(self.layout[:at]))
            hundredths = int(text[pre : pre + 2])
            dt = datetime.strptime(text[:pre] + text[pre + 2 :], self.layout.replace("%f2", ""))
            dt = dt.replace(microsecond=hundredths * 10000)
        else:
            dt = datetime.strptime(text, self.layout)
        if "%y" in self.layout and dt.year < 2000:
            dt = dt.replace(year=dt.year + 100)  # two-digit years: a camera clock lives in 2000..2099
        return dt

    def parse_text(self, text: str) -> Any:
        return datetime.now() if text == "now" else datetime.fromisoformat(text)

    def to_json(self, value: Any) -> Any:
        return value.isoformat() if isinstance(value, datetime) else value


@dataclass(frozen=True)
class Bitrate(Codec):
    """TOPOTEK BIT: `0M0000` (M = 1..8 Mbps) or `Kddddd` (kbps, 50..99999). User value: kbps."""

    unit: str = "kbps"
    width: int = 6
    kind: str = "number"

    def allowed(self) -> str:
        return "50..99999 kbps (1000..8000 in whole Mbps use the Mbps form)"

    def encode(self, value: Any, name: str = "value") -> bytes:
        v = _num(value, name, self)
        if not v.is_integer() or not 50 <= v <= 99999:
            raise FieldValueError(name, value, self.allowed())
        kbps = int(v)
        if kbps % 1000 == 0 and 1 <= kbps // 1000 <= 8:
            return b"0%d0000" % (kbps // 1000)
        return b"K%05d" % kbps

    def decode(self, raw: bytes) -> Any:
        if raw[:1] in (b"K", b"k") and len(raw) == 6 and raw[1:].isdigit():
            return int(raw[1:])
        if len(raw) in (2, 6) and raw[:2].isdigit():
            return int(raw[1:2]) * 1000
        if len(raw) == 1 and raw.isdigit():
            return int(raw) * 1000
        raise ValueError(f"{raw!r} is not 0M0000, Kddddd or a Mbps digit")

    @property
    def min_width(self) -> int:
        return 1

    def parse_text(self, text: str) -> Any:
        return int(text)


# -- a field ---------------------------------------------------------------------------------------


@dataclass(frozen=True)
class Field:
    """A named field of a form: the codec plus its description. `default` is used when a caller
    omits it (None means required).

    Sign metadata (read by the client and the simulator through `protocol.signs`, nowhere else):
    `axis` names the gimbal axis an angle or rate field measures, so the device model's
    `wire_signs` apply to it; `sign` is a fixed wire sign for fields whose document states their
    own convention (TOPOTEK UAV pitch is down-positive: -1)."""

    name: str
    codec: Codec
    description: str = ""
    default: Any = None
    axis: str | None = None
    sign: int = 1

    @property
    def unit(self) -> str:
        return self.codec.unit

    def describe(self) -> dict[str, Any]:
        d = {"name": self.name, "description": self.description, "default": self.default, "axis": self.axis}
        d.update(self.codec.describe())
        return d
