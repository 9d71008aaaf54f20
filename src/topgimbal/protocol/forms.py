"""Forms: the data layouts a command takes, one per control (`r`/`w`) and direction.

`request` is host -> device, `response` device -> host (answers, echoes and unsolicited reports).
A form is either a sequence of fields (only the last may have a variable width) or constant data
(a query's `00`)."""

from __future__ import annotations

from binascii import unhexlify
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from struct import Struct
from types import CodeType
from typing import Any

from ..errors import FieldValueError
from .fields import Codec, Field, HexInt

REQUEST = "request"
RESPONSE = "response"
FORM_ROLES = ("", "echo")  # "echo": the device's copy of a write; answers and reports leave it empty


# Compiled field decoders by source text (Form._build_decoder): the catalog has a few dozen layouts.
_COMPILED: dict[str, CodeType] = {}
_COMPILED_MAX = 1024


@dataclass(frozen=True)
class Form:
    """One data layout of a command: control, direction, fields (or constant data).

    `title` names the form for people (and selects it: `Dialect.encode(..., form=title)`);
    `section` is where a document defines it, when that differs from the command's own section."""

    rw: str
    direction: str
    fields: tuple[Field, ...] = ()
    const: bytes | None = None
    title: str = ""
    role: str = ""
    section: str = ""
    # Derived once: decode and encode are on hot paths.
    names: frozenset[str] = field(init=False, repr=False, compare=False, default=frozenset())
    # (field name, state key) of the fields that carry a catalog state key, in wire order
    keyed_fields: tuple[tuple[str, str], ...] = field(init=False, repr=False, compare=False, default=())
    _fixed: int = field(init=False, repr=False, compare=False, default=0)
    _variable: Codec | None = field(init=False, repr=False, compare=False, default=None)
    _slices: tuple[tuple[str, Codec, int, int], ...] = field(init=False, repr=False, compare=False, default=())
    _min_len: int = field(init=False, repr=False, compare=False, default=0)
    _max_len: int = field(init=False, repr=False, compare=False, default=0)
    # Built on first use (`decoder`): most forms of a dialect never decode a frame in a short run
    # (a one-frame `topgimbal decode`), and building them all was a third of a dialect's build.
    _decoder: Callable[[bytes], dict[str, Any]] | None = field(init=False, repr=False, compare=False, default=None)

    def __post_init__(self) -> None:
        if self.rw not in ("r", "w") or self.direction not in (REQUEST, RESPONSE) or self.role not in FORM_ROLES:
            raise ValueError(f"form {self.title!r}: rw r|w, direction request|response, role '' or 'echo'")
        if self.const is not None and self.fields:
            raise ValueError(f"form {self.title!r}: constant data and fields exclude each other")
        fixed = 0
        variable: Codec | None = None
        slices: list[tuple[str, Codec, int, int]] = []
        names = [f.name for f in self.fields]
        if len(set(names)) != len(names):
            raise ValueError(f"form {self.title!r}: a field name is used twice ({', '.join(names)})")
        for i, f in enumerate(self.fields):
            w = f.codec.width
            if w is None:
                if i != len(self.fields) - 1:
                    raise ValueError(f"only the last field may have a variable width ({f.name})")
                variable = f.codec
            else:
                slices.append((f.name, f.codec, fixed, fixed + w))
                fixed += w
        if self.const is not None:
            lo = hi = len(self.const)
        else:
            lo = fixed + (variable.min_width if variable else 0)
            hi = fixed + (variable.max_width if variable else 0)
        set_ = object.__setattr__
        set_(self, "names", frozenset(names))
        set_(self, "keyed_fields", tuple((f.name, f.state_key) for f in self.fields if f.state_key))
        set_(self, "_fixed", fixed)
        set_(self, "_variable", variable)
        set_(self, "_slices", tuple(slices))
        set_(self, "_min_len", lo)
        set_(self, "_max_len", hi)

    def _build_decoder(self) -> Callable[[bytes], dict[str, Any]]:
        """`decoder`: one function per form that calls each field's codec on its slice and builds
        the dict in one expression (no per-field loop or comprehension frame on the hot path)."""
        if self.const is not None:
            const = self.const

            def decode_const(data: bytes) -> dict[str, Any]:
                if data != const:
                    raise FieldValueError("data", data, f"exactly {const!r}")
                return {}

            return decode_const
        namespace: dict[str, Any] = {"_unhex": unhexlify}
        lines: list[str] = []
        items: list[str] = []
        for k, run in enumerate(_runs(self._slices)):
            name, codec, a, b = run[0]
            plans = [c.packed_plan() if isinstance(c, HexInt) else None for _n, c, _a, _b in run]
            if len(run) == 1 and plans[0] is None:
                namespace[f"_d{k}"] = codec.decode
                items.append(f"{name!r}: _d{k}(data[{a:d}:{b:d}])")
                continue
            # A run of packable hex fields: one unhexlify (which also rejects a non-hex digit with
            # a ValueError) and one unpack, then each value scaled as HexInt.decode scales it.
            namespace[f"_u{k}"] = Struct(">" + "".join(p[0] for p in plans if p)).unpack
            names = [f"_v{k}_{j}" for j in range(len(run))]
            lines.append(f"{', '.join(names)}, = _u{k}(_unhex(data[{a:d}:{run[-1][3]:d}]))")
            for j, ((fname, _c, _a, _b), plan) in enumerate(zip(run, plans, strict=True)):
                assert plan is not None
                _letter, div, scale, dec = plan
                namespace[f"_s{k}_{j}"] = div or scale
                if div:
                    expr = f"{names[j]} / _s{k}_{j}"
                elif scale == 1:
                    expr = names[j]
                else:
                    expr = f"_round({names[j]} * _s{k}_{j}, {dec:d})"
                items.append(f"{fname!r}: {expr}")
        namespace["_round"] = round
        if self._variable is not None:
            namespace["_dv"] = self._variable.decode
            items.append(f"{self.fields[-1].name!r}: _dv(data[{self._fixed:d}:])")
        # Built from field names (as literals), slice bounds and decimals (ints) only. Many forms
        # share one text (a write and its echo): compiled once, run in each form's own namespace.
        body = "".join(f"    {line}\n" for line in lines)
        source = f"def decode(data):\n{body}    return {{{', '.join(items)}}}\n"
        code = _COMPILED.get(source)
        if code is None:
            if len(_COMPILED) >= _COMPILED_MAX:
                _COMPILED.clear()
            code = _COMPILED[source] = compile(source, "<form decoder>", "exec")
        exec(code, namespace)
        return namespace["decode"]

    @property
    def decoder(self) -> Callable[[bytes], dict[str, Any]]:
        """The fields of data already of an accepted length, or ValueError (what `decode` does
        after its length check, without naming the field)."""
        dec = self._decoder
        if dec is None:
            dec = self._build_decoder()
            object.__setattr__(self, "_decoder", dec)
        return dec

    @property
    def min_length(self) -> int:
        return self._min_len

    @property
    def max_length(self) -> int:
        return self._max_len

    def accepts_length(self, n: int) -> bool:
        return self._min_len <= n <= self._max_len

    def describe(self) -> dict[str, Any]:
        """The form's metadata as JSON-able data (CLI `catalog --json`, the console's page)."""
        return {
            "rw": self.rw,
            "direction": self.direction,
            "title": self.title,
            "role": self.role,
            "section": self.section,
            "const": self.const.decode("latin-1") if self.const is not None else None,
            "fields": [f.describe() for f in self.fields],
        }

    def field(self, name: str) -> Field:
        for f in self.fields:
            if f.name == name:
                return f
        raise KeyError(name)

    def encode(self, values: Mapping[str, Any], where: str = "") -> bytes:
        """The data for `values` (user units); FieldValueError names what is wrong and what is allowed."""
        if self.const is not None:
            if values:
                raise FieldValueError(", ".join(sorted(values)), values, f"no fields ({where} sends {self.const!r})")
            return self.const
        unknown = values.keys() - self.names
        if unknown:
            allowed = ", ".join(f.name for f in self.fields) or "no fields"
            bad = sorted(unknown)[0]
            raise FieldValueError(bad, values[bad], f"a field of {where}: {allowed}")
        out = []
        for f in self.fields:
            if f.name in values:
                value = values[f.name]
            elif f.default is not None:
                value = f.default
            else:
                raise FieldValueError(f.name, None, f"a value ({f.codec.allowed()}); {where} requires it")
            out.append(f.codec.encode(value, f.name))
        return b"".join(out)

    def decode(self, data: bytes) -> dict[str, Any]:
        """Named values in user units; FieldValueError (a ValueError) when the data do not fit."""
        if self.const is not None:
            if data != self.const:
                raise FieldValueError("data", data, f"exactly {self.const!r}")
            return {}
        n = len(data)
        if not self._min_len <= n <= self._max_len:
            raise FieldValueError("data", data, f"{self._min_len}..{self._max_len} data bytes, not {n}")
        try:
            return (self._decoder or self.decoder)(data)
        except ValueError:
            self._raise_for_field(data)
            raise

    def _raise_for_field(self, data: bytes) -> None:
        """Which field's bytes failed, as a FieldValueError naming it (only on the error path)."""
        spans = [(f, a, b) for (_n, _c, a, b), f in zip(self._slices, self.fields, strict=False)]
        if self._variable is not None:
            spans.append((self.fields[-1], self._fixed, len(data)))
        for f, a, b in spans:
            try:
                f.codec.decode(data[a:b])
            except ValueError as exc:
                raise FieldValueError(f.name, data[a:b], f"{f.codec.allowed()} ({exc})") from None

    def is_idempotent(self, data: bytes) -> bool:
        """False if any enum value in `data` is a toggle or relative step."""
        for _name, codec, a, b in self._slices:
            check = getattr(codec, "is_idempotent", None)
            if check is not None and not check(data[a:b]):
                return False
        return True


def _runs(slices: tuple[tuple[str, Codec, int, int], ...]) -> list[list[tuple[str, Codec, int, int]]]:
    """Fixed fields in wire order, grouped: adjacent HexInt fields with a packed plan share a run
    (decoded together), every other field is a run of its own."""
    runs: list[list[tuple[str, Codec, int, int]]] = []
    packable_before = False
    for item in slices:
        codec = item[1]
        packable = isinstance(codec, HexInt) and codec.packed_plan() is not None
        if packable and packable_before:
            runs[-1].append(item)
        else:
            runs.append([item])
        packable_before = packable
    return runs


QUERY = Form("r", REQUEST, const=b"00", title="query")

__all__ = ["FORM_ROLES", "QUERY", "REQUEST", "RESPONSE", "Form"]
