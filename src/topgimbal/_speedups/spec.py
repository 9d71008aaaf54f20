"""Codec descriptors: what the C core needs to know about one catalog codec, read from its public
attributes. Shared by the C table generator (`tools/cgen.py`) and the fast path's runtime tables,
so the two cannot disagree.

Dispatch is on the codec's class name (`HexInt`, `Enum`, ...): `kind` alone does not say how a
number is spelled (hex, decimal, binary). A class without a handler raises `CodecSpecError`
naming it: a new codec kind must be taught here (one small handler) and in `c/src/tg_codec.c`.

Duck-typed on purpose: this package sits below `protocol/` and imports nothing from topgimbal at
all (not even for types): each handler reads the public attributes of the class it is keyed by.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Iterable, Sequence
from dataclasses import dataclass, field
from decimal import Decimal
from typing import Any, Protocol, TypedDict

# Kind codes shared with c/include/topgimbal.h (enum tg_kind). Append only.
KINDS = (
    "hexint",
    "decint",
    "binint",
    "decfloat",
    "bitrate",
    "enum",
    "oneof",
    "text",
    "ipv4",
    "raw",
    "literal",
    "geodm",
    "geodeg",
    "timestamp",
)
KIND_CODE = {k: i + 1 for i, k in enumerate(KINDS)}

# Codecs the Python fast path hands back to the Python codec (rare fields whose Python value is
# not a number, a name or plain text: datetime, normalised text, coordinates).
DELEGATED = frozenset({"ipv4", "geodm", "geodeg", "timestamp"})

MAX_EXP = 9  # finest decimal step the fixed-point representation carries (10^-9)


class CodecSpecError(ValueError):
    """A codec the C core cannot represent (unknown class, or a scale it would round)."""


@dataclass(frozen=True)
class CodecSpec:
    """One codec as the C core sees it. Numbers are fixed point: user value = mantissa * 10^exp10,
    mantissa = wire integer * mul. `lo`/`hi` bound the mantissa for encoding (inclusive)."""

    kind: str
    width: int | None  # fixed number of data bytes, None when variable
    min_width: int
    max_width: int
    signed: bool = False
    little: bool = False
    exp10: int = 0
    mul: int = 1
    lo: int = 0
    hi: int = 0
    pyfloat: bool = False  # the Python codec returns a float (else an int)
    decimals: int = 0  # decfloat: digits after the point
    pad: int = 0  # decfloat (variable width): zero padding on encode
    none_tokens: tuple[bytes, ...] = ()
    names: tuple[str, ...] = ()  # enum: value names, in catalog order
    raws: tuple[bytes, ...] = ()  # enum: canonical spelling of each value
    idempotent: tuple[bool, ...] = ()
    spellings: tuple[tuple[bytes, int], ...] = ()  # enum: accepted spelling -> value index
    text: bytes = b""  # literal text, or timestamp layout
    lat: bool = False  # geo: latitude (else longitude)
    binary: bool = False  # raw: any byte allowed (else '#', CR and LF are refused on encode)
    sub: CodecSpec | None = None  # oneof: the number codec
    extra: dict[str, object] = field(default_factory=dict, compare=False)

    @property
    def code(self) -> int:
        return KIND_CODE[self.kind]


def _scale_parts(scale: float, where: str) -> tuple[int, int]:
    """(mul, exp10) with scale == mul * 10^exp10 exactly (as the decimal the catalog wrote)."""
    d = Decimal(repr(float(scale))).normalize()
    sign, digits, exp = d.as_tuple()
    assert isinstance(exp, int)
    if sign or not digits or d == 0:
        raise CodecSpecError(f"{where}: scale {scale!r} must be positive")
    mantissa = int("".join(map(str, digits)))
    if exp > 0:
        return mantissa * 10**exp, 0
    if -exp > MAX_EXP:
        raise CodecSpecError(f"{where}: scale {scale!r} is finer than 10^-{MAX_EXP}")
    return mantissa, exp


def _python_decimals(scale: float) -> int:
    """The number of decimals the Python number codecs round a scaled value to."""
    if scale >= 1 and float(scale).is_integer():
        return 0
    return max(0, -math.floor(math.log10(scale) + 1e-9)) if scale < 1 else 0


def _bounds(lo: float, hi: float, exp10: int) -> tuple[int, int]:
    """Mantissa bounds: every grid value v with lo - 1e-9 <= v <= hi + 1e-9 (the Python check)."""
    step = Decimal(10) ** exp10
    eps = Decimal("1e-9")
    lo_m = math.ceil((Decimal(repr(float(lo))) - eps) / step)
    hi_m = math.floor((Decimal(repr(float(hi))) + eps) / step)
    return lo_m, hi_m


class _Ranged(Protocol):
    """What `_number` reads of a number codec (HexInt, DecInt, BinInt)."""

    @property
    def scale(self) -> float: ...
    @property
    def min(self) -> float | None: ...
    @property
    def max(self) -> float | None: ...


class _NumberParts(TypedDict):
    mul: int
    exp10: int
    lo: int
    hi: int
    pyfloat: bool


def _number(codec: _Ranged, where: str, kind: str, exact_div: bool) -> _NumberParts:
    scale = codec.scale
    mul, exp10 = _scale_parts(scale, where)
    if scale != 1:
        inv = 1 / scale
        div_exact = exact_div and scale < 1 and abs(inv - round(inv)) < 1e-9
        if not div_exact and -exp10 > _python_decimals(scale):
            raise CodecSpecError(
                f"{where}: scale {scale!r} has more decimals than the Python codec keeps ({_python_decimals(scale)})"
            )
    if codec.min is None or codec.max is None:  # the codecs derive both from the width
        raise CodecSpecError(f"{where}: a number codec without a range")
    lo, hi = _bounds(codec.min, codec.max, exp10)
    return {"mul": mul, "exp10": exp10, "lo": lo, "hi": hi, "pyfloat": scale != 1}


def _hexint(c: Any, where: str) -> CodecSpec:
    n = _number(c, where, "hexint", exact_div=True)
    if n["hi"] // n["mul"] >= 16**c.width or n["lo"] // n["mul"] < -(16**c.width):
        raise CodecSpecError(f"{where}: range {c.min}..{c.max} does not fit {c.width} hex digits")
    return CodecSpec(
        "hexint", c.width, c.width, c.width, signed=bool(c.signed), none_tokens=tuple(c.none_tokens or ()), **n
    )


def _decint(c: Any, where: str) -> CodecSpec:
    return CodecSpec("decint", c.width, c.width, c.width, **_number(c, where, "decint", exact_div=False))


def _binint(c: Any, where: str) -> CodecSpec:
    order = getattr(c, "byteorder", "little")
    if order not in ("little", "big"):
        raise CodecSpecError(f"{where}: byte order {order!r}")
    n = _number(c, where, "binint", exact_div=False)
    return CodecSpec("binint", c.width, c.width, c.width, signed=bool(c.signed), little=order == "little", **n)


def _decfloat(c: Any, where: str) -> CodecSpec:
    dec = int(c.decimals)
    if dec > MAX_EXP:
        raise CodecSpecError(f"{where}: {dec} decimals")
    lo, hi = _bounds(c.min, c.max, -dec)
    w = c.width
    return CodecSpec(
        "decfloat",
        w,
        w if w is not None else c.min_width,
        w if w is not None else c.max_width,
        exp10=-dec,
        lo=lo,
        hi=hi,
        pyfloat=True,
        decimals=dec,
        pad=int(getattr(c, "pad", 0) or 0),
        none_tokens=tuple(c.none_tokens or ()),
    )


def _bitrate(c: Any, where: str) -> CodecSpec:
    if getattr(c, "scale", 1) != 1:
        raise CodecSpecError(f"{where}: a Bitrate scale of {c.scale!r} (the C core counts whole kbps)")
    return CodecSpec("bitrate", c.width, c.min_width, c.max_width, lo=int(c.min), hi=int(c.max))


class _EnumTables(TypedDict):
    names: tuple[str, ...]
    raws: tuple[bytes, ...]
    idempotent: tuple[bool, ...]
    spellings: tuple[tuple[bytes, int], ...]


def _enum_tables(c: Any, where: str) -> _EnumTables:
    values = tuple(c.values)
    raws = tuple(v.raw.encode("latin-1") for v in values)
    # Resolve spellings exactly as the Python codec builds its dictionary: the exact spelling
    # of every value first wins over another's lower-case variant; the later duplicate wins.
    table: dict[bytes, int] = {}
    for i, raw in enumerate(raws):
        table[raw] = i
        table.setdefault(raw.lower(), i)
    if any(len(r) != c.width for r in raws):
        raise CodecSpecError(f"{where}: enum spelling of the wrong width")
    return {
        "names": tuple(v.name for v in values),
        "raws": raws,
        "idempotent": tuple(bool(v.idempotent) for v in values),
        "spellings": tuple(table.items()),
    }


def _enum(c: Any, where: str) -> CodecSpec:
    return CodecSpec("enum", c.width, c.width, c.width, **_enum_tables(c, where))


def _oneof(c: Any, where: str) -> CodecSpec:
    number = codec_spec(c.number, where + " (number)")
    tokens = c.tokens
    if number.width != tokens.width:
        raise CodecSpecError(f"{where}: token and number widths differ")
    return CodecSpec("oneof", tokens.width, tokens.width, tokens.width, sub=number, **_enum_tables(tokens, where))


def _text(c: Any, where: str) -> CodecSpec:
    return CodecSpec("text", None, c.min_width, c.max_width)


def _ipv4(c: Any, where: str) -> CodecSpec:
    return CodecSpec("ipv4", None, c.min_width, c.max_width)


def _raw(c: Any, where: str) -> CodecSpec:
    return CodecSpec("raw", c.width, c.min_width, c.max_width, binary=bool(getattr(c, "binary", False)))


def _literal(c: Any, where: str) -> CodecSpec:
    t = c.text.encode("latin-1")
    return CodecSpec("literal", len(t), len(t), len(t), text=t)


GEO_STYLES = {"dm": "geodm", "deg": "geodeg"}  # Geo(axis, style): the C kind of each style


def _geo(c: Any, where: str) -> CodecSpec:
    kind = GEO_STYLES.get(c.style)
    if c.axis not in ("lat", "lon") or kind is None:
        raise CodecSpecError(f"{where}: Geo axis {c.axis!r} style {c.style!r} (the C core knows lat|lon, dm|deg)")
    lat = c.axis == "lat"
    lim = 90 if lat else 180
    if c.width != (10 if lat else 11):
        raise CodecSpecError(f"{where}: a {c.axis} coordinate of {c.width} characters")
    return CodecSpec(kind, c.width, c.width, c.width, exp10=-7, lo=-lim * 10**7, hi=lim * 10**7, pyfloat=True, lat=lat)


_LAYOUT_FIELDS = {"%Y": 4, "%y": 2, "%m": 2, "%d": 2, "%H": 2, "%M": 2, "%S": 2, "%f2": 2}


def _timestamp(c: Any, where: str) -> CodecSpec:
    layout = c.layout
    i, width = 0, 0
    while i < len(layout):
        if layout[i] == "%":
            tok = layout[i : i + 3] if layout[i : i + 3] == "%f2" else layout[i : i + 2]
            if tok not in _LAYOUT_FIELDS:
                raise CodecSpecError(f"{where}: layout directive {tok!r} is not known to the C core")
            width += _LAYOUT_FIELDS[tok]
            i += len(tok)
        else:
            if not 0x20 < ord(layout[i]) < 0x7F:
                raise CodecSpecError(f"{where}: layout character {layout[i]!r}")
            width += 1
            i += 1
    if width != c.width:
        raise CodecSpecError(f"{where}: layout {layout!r} is {width} characters, codec says {c.width}")
    return CodecSpec("timestamp", width, width, width, text=layout.encode("ascii"))


HANDLERS: dict[str, Callable[[Any, str], CodecSpec]] = {
    "HexInt": _hexint,
    "DecInt": _decint,
    "BinInt": _binint,
    "DecFloat": _decfloat,
    "Bitrate": _bitrate,
    "Enum": _enum,
    "OneOf": _oneof,
    "Text": _text,
    "IPv4Text": _ipv4,
    "RawData": _raw,
    "Literal": _literal,
    "Geo": _geo,
    "Timestamp": _timestamp,
}


def codec_spec(codec: object, where: str = "") -> CodecSpec:
    """The C descriptor of `codec`; CodecSpecError for a codec class the C core does not know."""
    name = type(codec).__name__
    handler = HANDLERS.get(name)
    if handler is None:
        raise CodecSpecError(
            f"{where or 'a field'}: codec class {name!r} (kind {getattr(codec, 'kind', '?')!r}) is not known to "
            "the C core; add a handler to topgimbal/_speedups/spec.py and a case to c/src/tg_codec.c"
        )
    return handler(codec, where)


def decode_order(forms: Sequence[_FormKey], rw: str, direction: str) -> list[int]:
    """Dialect.decode's form order for (rw, direction): that direction's forms, then the other's
    (frames whose addresses are not swapped, errata E5). `forms` is a CommandSpec's forms."""
    own = [i for i, f in enumerate(forms) if f.rw == rw and f.direction == direction]
    rest = [i for i, f in enumerate(forms) if f.rw == rw and f.direction != direction]
    return own + rest


class _FormKey(Protocol):
    @property
    def rw(self) -> str: ...
    @property
    def direction(self) -> str: ...


# The extension's own layouts (build_codec, Decoder_init in _ctop.c): opaque to Python.
CodecTuple = tuple[object, ...]


def codec_tuple(spec: CodecSpec) -> CodecTuple:
    """The descriptor as the extension's Decoder reads it (see build_codec in _ctop.c)."""
    return (
        spec.code,
        spec.width or 0,
        spec.min_width,
        spec.max_width,
        int(spec.signed),
        int(spec.little),
        int(spec.lat),
        int(spec.binary),
        int(spec.pyfloat),
        spec.exp10,
        spec.decimals,
        spec.pad,
        spec.mul,
        spec.lo,
        spec.hi,
        spec.raws,
        spec.spellings,
        spec.none_tokens,
        spec.text,
        codec_tuple(spec.sub) if spec.sub is not None else None,
    )


def decoder_tables(commands: Iterable[Any]) -> tuple[CodecTuple, ...]:
    """A dialect's commands (Dialect.commands.values()) as the extension's Decoder takes them.
    Fields whose codec the C core does not decode natively carry only their Python codec."""
    out = []
    for cmd in commands:
        forms = []
        for form in cmd.forms:
            fields = []
            offset = 0
            for f in form.fields:
                try:
                    cs: CodecSpec | None = codec_spec(f.codec, f"{cmd.ident}.{f.name}")
                except CodecSpecError:
                    cs = None  # a codec kind the C core does not know yet: Python decodes it
                native = cs is not None and cs.kind not in DELEGATED
                width = f.codec.width or 0
                fields.append(
                    (
                        f.name,
                        offset,
                        width,
                        codec_tuple(cs) if native and cs is not None else None,
                        f.codec,
                        cs.names if native and cs is not None and cs.names else None,
                        cs.text.decode("latin-1") if native and cs is not None and cs.kind == "literal" else None,
                    )
                )
                offset += width
            forms.append((form, form.const, form.min_length, form.max_length, tuple(fields)))
        orders = tuple(
            tuple(tuple(decode_order(cmd.forms, rw, direction)) for direction in ("request", "response"))
            for rw in ("r", "w")
        )
        out.append((cmd.ident.encode("latin-1"), cmd, tuple(forms), orders))
    return tuple(out)
