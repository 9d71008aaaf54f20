"""Catalog structures: forms, command specs, device models, dialects, typed messages.

A *command* (`CommandSpec`) is one identifier in one dialect. It has *forms*: the data layouts it
takes in each direction (`request` host -> device, `response` device -> host, which includes
unsolicited reports) and control (`r`/`w`). A *dialect* is an explicit object holding its
commands and device models; nothing here is global, two dialects live side by side.
"""

from __future__ import annotations

from collections.abc import Iterable, Mapping
from dataclasses import dataclass, field
from functools import cached_property
from typing import Any, NamedTuple

from ..errors import FieldValueError, UnknownCommandError, UnsupportedError
from .fields import Codec, Field
from .frame import DEVICE_ADDRESSES, HOST_ADDRESSES, MAX_LENGTH, Frame, make_frame

REQUEST = "request"
RESPONSE = "response"


@dataclass(frozen=True)
class Form:
    """One data layout of a command: control, direction, fields (or constant data)."""

    rw: str
    direction: str
    fields: tuple[Field, ...] = ()
    const: bytes | None = None
    title: str = ""
    role: str = ""  # "echo" for the device's copy of a write; reports and answers leave it empty

    def __post_init__(self) -> None:
        fixed = 0
        variable: Codec | None = None
        slices: list[tuple[str, Codec, int, int]] = []
        for i, f in enumerate(self.fields):
            w = f.codec.width
            if w is None:
                if i != len(self.fields) - 1:
                    raise ValueError(f"only the last field may have a variable width ({f.name})")
                variable = f.codec
            else:
                slices.append((f.name, f.codec, fixed, fixed + w))
                fixed += w
        object.__setattr__(self, "_fixed", fixed)
        object.__setattr__(self, "_variable", variable)
        object.__setattr__(self, "_slices", tuple(slices))
        if self.const is not None:
            lo = hi = len(self.const)
        else:
            lo = fixed + (variable.min_width if variable else 0)
            hi = fixed + (variable.max_width if variable else 0)
        object.__setattr__(self, "_min_len", lo)
        object.__setattr__(self, "_max_len", hi)
        object.__setattr__(self, "names", frozenset(f.name for f in self.fields))

    @property
    def min_length(self) -> int:
        return self._min_len  # type: ignore[attr-defined,no-any-return]

    @property
    def max_length(self) -> int:
        return self._max_len  # type: ignore[attr-defined,no-any-return]

    def accepts_length(self, n: int) -> bool:
        return self._min_len <= n <= self._max_len  # type: ignore[attr-defined,no-any-return]

    def describe(self) -> dict[str, Any]:
        """The form's metadata as JSON-able data (CLI `catalog --json`, the console's page)."""
        return {
            "rw": self.rw,
            "direction": self.direction,
            "title": self.title,
            "role": self.role,
            "const": self.const.decode("latin-1") if self.const is not None else None,
            "fields": [f.describe() for f in self.fields],
        }

    def field(self, name: str) -> Field:
        for f in self.fields:
            if f.name == name:
                return f
        raise KeyError(name)

    def encode(self, values: Mapping[str, Any], where: str = "") -> bytes:
        if self.const is not None:
            extra = set(values)
            if extra:
                raise FieldValueError(", ".join(sorted(extra)), values, f"no fields ({where} sends {self.const!r})")
            return self.const
        unknown = values.keys() - self.names  # type: ignore[attr-defined]
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
        """Named values in user units; raises ValueError when the data do not fit this form."""
        if self.const is not None:
            if data != self.const:
                raise ValueError(f"expected {self.const!r}")
            return {}
        n = len(data)
        if not self._min_len <= n <= self._max_len:  # type: ignore[attr-defined]
            raise ValueError(f"{n} data bytes, this form takes {self.min_length}..{self.max_length}")
        out = {name: codec.decode(data[a:b]) for name, codec, a, b in self._slices}  # type: ignore[attr-defined]
        if self._variable is not None:  # type: ignore[attr-defined]
            out[self.fields[-1].name] = self._variable.decode(data[self._fixed :])  # type: ignore[attr-defined]
        return out

    def is_idempotent(self, data: bytes) -> bool:
        """False if any enum value in `data` is a toggle or relative step."""
        for _name, codec, a, b in self._slices:  # type: ignore[attr-defined]
            check = getattr(codec, "is_idempotent", None)
            if check is not None and not check(data[a:b]):
                return False
        return True


@dataclass(frozen=True)
class CommandSpec:
    """One identifier of one dialect, as data."""

    ident: str
    name: str
    title: str
    address: str  # default destination (device address class)
    forms: tuple[Form, ...]
    section: str  # where the document defines it ("SkyDroid §3.1", "beyond the documents: ...")
    models: frozenset[str] | None = None  # None: every model of the dialect
    addresses: tuple[str, ...] = ()  # other destinations the command is also sent to
    header: str | None = None  # header the document uses for this command, when it insists
    documented: bool = True  # False for commands real clients use beyond the documents
    echo: bool = True  # writes are echoed by the device (the protocol's rule)
    repeatable: bool = True  # False: each write acts again (a photo), never retried
    motion: bool = False  # moves the gimbal (some firmware does not echo these)
    notes: str = ""

    def describe(self) -> dict[str, Any]:
        """The command's metadata as JSON-able data; `models` is None when every model has it."""
        return {
            "id": self.ident,
            "name": self.name,
            "title": self.title,
            "address": self.address,
            "section": self.section,
            "models": sorted(self.models) if self.models is not None else None,
            "readable": self.readable,
            "writable": self.writable,
            "documented": self.documented,
            "repeatable": self.repeatable,
            "motion": self.motion,
            "notes": self.notes,
            "forms": [f.describe() for f in self.forms],
        }

    @cached_property
    def signed_fields(self) -> tuple[tuple[str, str | None, int], ...]:
        """(name, axis, fixed sign) of every field with sign metadata; same-named fields of one
        command share it across forms. Computed once (read on the client's telemetry path)."""
        seen: dict[str, tuple[str, str | None, int]] = {}
        for form in self.forms:
            for f in form.fields:
                if (f.axis or f.sign != 1) and f.name not in seen:
                    seen[f.name] = (f.name, f.axis, f.sign)
        return tuple(seen.values())

    @cached_property
    def _by_rw_direction(self) -> dict[tuple[str, str], tuple[Form, ...]]:
        out: dict[tuple[str, str], tuple[Form, ...]] = {}
        for f in self.forms:
            out[(f.rw, f.direction)] = (*out.get((f.rw, f.direction), ()), f)
        return out

    def forms_for(self, rw: str, direction: str) -> list[Form]:
        return list(self._by_rw_direction.get((rw, direction), ()))

    @property
    def readable(self) -> bool:
        return bool(self.forms_for("r", REQUEST))

    @property
    def writable(self) -> bool:
        return bool(self.forms_for("w", REQUEST))

    def request_form(self, rw: str, keys: Iterable[str] = ()) -> Form:
        forms = self._by_rw_direction.get((rw, REQUEST), ())
        if not forms:
            what = "read (r)" if rw == "r" else "written (w)"
            raise UnsupportedError(f"{self.ident} cannot be {what} by a host in this dialect")
        if len(forms) == 1:
            return forms[0]
        keys = set(keys)
        for f in forms:
            if keys <= f.names:  # type: ignore[attr-defined]
                return f
        return forms[0]

    def response_form(self, rw: str, data: bytes) -> Form | None:
        for f in self.forms_for(rw, RESPONSE):
            if f.accepts_length(len(data)):
                try:
                    f.decode(data)
                except (ValueError, UnicodeDecodeError):
                    continue
                return f
        return None

    def is_idempotent(self, frame: Frame) -> bool:
        """Whether sending `frame` twice has the effect of sending it once (safe to retry)."""
        if frame.rw == "r":
            return True
        if not self.repeatable:
            return False
        for f in self.forms_for("w", REQUEST):
            if f.accepts_length(len(frame.data)):
                return f.is_idempotent(frame.data)
        return True


@dataclass(frozen=True)
class Endpoint:
    kind: str  # "udp", "tcp" or "serial"
    port: int | None = None
    note: str = ""

    def __str__(self) -> str:
        return f"{self.kind.upper()} {self.port}" if self.port is not None else f"{self.kind} {self.note}".strip()


@dataclass(frozen=True)
class DeviceModel:
    """One camera model: its dialect, documented endpoints, mechanical limits and features."""

    name: str
    dialect: str
    title: str
    endpoints: tuple[Endpoint, ...]
    yaw_range_deg: tuple[float, float] = (-90.0, 90.0)
    pitch_range_deg: tuple[float, float] = (-90.0, 90.0)
    roll_range_deg: tuple[float, float] = (-90.0, 90.0)
    max_rate_deg_s: float = 60.0
    max_accel_deg_s2: float = 300.0
    thermal: bool = False
    visible_lenses: int = 1
    optical_zoom_max: float = 1.0
    digital_zoom_max: float = 4.0
    lrf_range_m: tuple[float, float] | None = None
    limits: Mapping[tuple[str, str], tuple[float, float]] = field(default_factory=dict)
    host_address: str = "U"
    # Wire sign per axis relative to the API convention (yaw right-positive, pitch up-positive,
    # roll right-positive): -1 where the device's wire value is the opposite. Applies to angle
    # commands, rate commands and attitude reports alike. Users may override per device.
    wire_signs: Mapping[str, int] = field(default_factory=lambda: {"yaw": 1, "pitch": 1, "roll": 1})
    notes: str = ""


class Message(NamedTuple):
    """A decoded frame: the spec and form it matched and its fields in user units.

    `fields` is None (and `error` says why) when the identifier is unknown or the data fit no form.
    A tuple, because the parser and decoder build one per frame on the hot path."""

    frame: Frame
    spec: CommandSpec | None
    form: Form | None
    fields: dict[str, Any] | None
    error: str | None = None

    @property
    def ident(self) -> str:
        return self.frame.ident

    @property
    def is_error(self) -> bool:
        return self.frame.ident == "ERE"

    def to_dict(self) -> dict[str, Any]:
        fields = None
        if self.fields is not None and self.form is not None:
            codecs = {f.name: f.codec for f in self.form.fields}
            fields = {k: (codecs[k].to_json(v) if k in codecs else v) for k, v in self.fields.items()}
        return {
            "id": self.frame.ident,
            "name": self.spec.name if self.spec else None,
            "rw": self.frame.rw,
            "src": self.frame.src,
            "dst": self.frame.dst,
            "fields": fields,
            "error": self.error,
        }


def direction_of(frame: Frame) -> str:
    """`response` for device -> host frames, `request` otherwise."""
    return RESPONSE if frame.src in DEVICE_ADDRESSES and frame.dst in HOST_ADDRESSES else REQUEST


class Dialect:
    """All commands and device models of one vendor document. Immutable once built."""

    def __init__(
        self,
        name: str,
        title: str,
        commands: Iterable[CommandSpec],
        models: Iterable[DeviceModel],
        *,
        host_addresses: str = "U",
        headers: tuple[str, ...] = ("#TP", "#tp"),
        gimbal_header: str | None = None,
        options: Mapping[str, Any] | None = None,
    ) -> None:
        self.name = name
        self.title = title
        self.host_addresses = host_addresses
        self.headers = headers
        self.gimbal_header = gimbal_header
        self.options = dict(options or {})
        cmds: dict[str, CommandSpec] = {}
        for c in commands:
            if c.ident in cmds:
                raise ValueError(f"{name}: {c.ident} defined twice")
            cmds[c.ident] = c
        self.commands: Mapping[str, CommandSpec] = cmds
        self.models: Mapping[str, DeviceModel] = {m.name: m for m in models}
        # (ident, rw, direction) -> forms to try: the direction's own first, then the other
        # direction's, for frames whose addresses are not swapped (several document examples,
        # errata E5). Built once: decode is on the hot path.
        index: dict[tuple[str, str, str], tuple[Form, ...]] = {}
        for c in cmds.values():
            for rw in ("r", "w"):
                for direction, other in ((REQUEST, RESPONSE), (RESPONSE, REQUEST)):
                    index[(c.ident, rw, direction)] = tuple(c.forms_for(rw, direction)) + tuple(c.forms_for(rw, other))
        self._decode_index = index

    def __repr__(self) -> str:
        return f"<Dialect {self.name}: {len(self.commands)} commands, models {', '.join(self.models)}>"

    # -- lookup ------------------------------------------------------------------------------

    def command(self, ident: str) -> CommandSpec:
        spec = self.commands.get(ident) or self.commands.get(ident.upper())
        if spec is None:
            by_name = {c.name: c for c in self.commands.values()}
            spec = by_name.get(ident)
        if spec is None:
            raise UnknownCommandError(
                f"{ident!r} is not a command of the {self.name} dialect; known: {', '.join(sorted(self.commands))}"
            )
        return spec

    def model(self, name: str) -> DeviceModel:
        for m in self.models.values():
            if m.name.lower() == name.lower():
                return m
        raise UnknownCommandError(f"{name!r} is not a {self.name} model; known: {', '.join(self.models)}")

    def supports(self, model: str | DeviceModel, ident: str) -> bool:
        name = model.name if isinstance(model, DeviceModel) else model
        spec = self.commands.get(ident)
        if spec is None:
            return False
        return spec.models is None or name in spec.models

    def supported(self, model: str | DeviceModel) -> list[CommandSpec]:
        return [c for c in self.commands.values() if self.supports(model, c.ident)]

    def header_for(self, spec: CommandSpec | None, n: int, dst: str = "") -> str:
        if spec is not None and spec.header is not None and n <= MAX_LENGTH[spec.header]:
            return spec.header
        if self.gimbal_header and (dst == "G" or (spec is not None and spec.address == "G")) and n <= 15:
            return self.gimbal_header
        if n == 2:
            return "#TP"
        if n <= 0x0F:
            return "#tp"
        if n <= 0xFF and "#tP" in self.headers:
            return "#tP"
        if "#Tp" in self.headers:
            return "#Tp"
        raise FieldValueError("data", n, f"at most 15 data bytes in the {self.name} dialect")

    # -- encode / decode -----------------------------------------------------------------------

    def encode(
        self,
        ident: str,
        *,
        read: bool = False,
        src: str | None = None,
        dst: str | None = None,
        header: str | None = None,
        **values: Any,
    ) -> Frame:
        """The request frame for `ident` with field values in user units."""
        spec = self.command(ident)
        rw = "r" if read else "w"
        form = spec.request_form(rw, values)
        data = form.encode(values, f"{spec.ident} ({'read' if read else 'write'})")
        dst = dst or spec.address
        return make_frame(
            spec.ident,
            data,
            src=src or self.host_addresses[0],
            dst=dst,
            rw=rw,
            header=header or self.header_for(spec, len(data), dst),
        )

    def response(self, request: Frame, *, rw: str | None = None, header: str | None = None, **values: Any) -> Frame:
        """The device's answer to `request` (addresses swapped) with field values in user units."""
        spec = self.command(request.ident)
        rw = rw or request.rw
        forms = spec.forms_for(rw, RESPONSE)
        if not forms:
            raise UnsupportedError(f"{spec.ident} has no {rw!r} response form in the {self.name} dialect")
        keys = values.keys()
        form = next((f for f in forms if keys <= f.names), forms[0])  # type: ignore[attr-defined]
        data = form.encode(values, f"{spec.ident} response")
        return make_frame(
            spec.ident,
            data,
            src=request.dst,
            dst=request.src,
            rw=rw,
            header=header or self.header_for(spec, len(data), request.dst),
        )

    def notification(
        self,
        ident: str,
        *,
        src: str | None = None,
        dst: str = "U",
        rw: str | None = None,
        header: str | None = None,
        **values: Any,
    ) -> Frame:
        """An unsolicited device -> host frame (attitude stream, ZMP, LRF result, target solution).
        Echo forms are passed over: an echo answers a write, it is never sent on its own."""
        spec = self.command(ident)
        forms = [f for f in spec.forms if f.direction == RESPONSE and f.role != "echo" and (rw is None or f.rw == rw)]
        keys = values.keys()
        form = next((f for f in forms if keys <= f.names and f.fields), None)  # type: ignore[attr-defined]
        if form is None:
            raise UnsupportedError(f"{spec.ident} has no matching device -> host form in the {self.name} dialect")
        data = form.encode(values, f"{spec.ident} report")
        src = src or spec.address
        return make_frame(
            spec.ident, data, src=src, dst=dst, rw=form.rw, header=header or self.header_for(spec, len(data), src)
        )

    def decode(self, frame: Frame) -> Message:
        """Name the fields of `frame` in user units (never raises)."""
        spec = self.commands.get(frame.ident)
        if spec is None:
            return Message(frame, None, None, None, f"{frame.ident!r} is not in the {self.name} catalog")
        direction = RESPONSE if frame.src in DEVICE_ADDRESSES and frame.dst in HOST_ADDRESSES else REQUEST
        rw = frame.rw or "w"
        data = frame.data
        forms = self._decode_index[(frame.ident, rw, direction)]
        last_error = f"{spec.ident} has no {rw!r} form for a {direction}"
        for form in forms:
            if not form.accepts_length(len(data)):
                last_error = f"{len(data)} data bytes; {spec.ident} ({rw}) takes " + " or ".join(
                    f"{f.min_length}" + (f"..{f.max_length}" if f.max_length != f.min_length else "") for f in forms
                )
                continue
            try:
                return Message(frame, spec, form, form.decode(data))
            except (ValueError, UnicodeDecodeError) as exc:
                last_error = f"{spec.ident}: {exc}"
        return Message(frame, spec, None, None, last_error)

    def check_values(self, model: DeviceModel, ident: str, values: Mapping[str, Any]) -> None:
        """Raise if `model` does not support `ident` or a value is outside the model's limits."""
        if not self.supports(model, ident):
            raise UnsupportedError(f"the {model.name} does not support {ident} ({self.command(ident).title})")
        for (lim_ident, fname), (lo, hi) in model.limits.items():
            value = values.get(fname)
            if lim_ident == ident and isinstance(value, (int, float)) and not lo <= value <= hi:
                raise FieldValueError(fname, value, f"{lo:g}..{hi:g} on the {model.name}")
