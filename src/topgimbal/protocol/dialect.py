"""A dialect: the commands and model profiles of one vendor document, with encode and decode.

A `Dialect` is an explicit, immutable object; two live side by side and nothing here is global.
It answers what programs need without branching on its name: which models support a command
(from the profiles), the command holding a role (`by_role`), how to encode a request or an answer,
and what a received frame means (`decode`, which never raises)."""

from __future__ import annotations

from collections.abc import Callable, Iterable, Mapping
from dataclasses import replace
from functools import partial
from typing import Any

from .. import _speedups
from ..errors import FieldValueError, UnknownCommandError, UnsupportedError
from .commands import MANY_ROLES, ROLES, CommandSpec
from .forms import REQUEST, RESPONSE, Form
from .frame import DEVICE_ADDRESSES, HOST_ADDRESSES, MAX_LENGTH, Frame, make_frame
from .message import LazyText, Message
from .models import DeviceModel

NO_CONTROL_HEADER = "#Tp"  # its control position carries length: such a frame has no r/w
_HotForm = tuple[Form, int, int, Callable[[bytes], dict[str, Any]]]
_new_tuple = tuple.__new__


class Dialect:
    """All commands and device models of one vendor document. Immutable once built.

    `destinations` moves commands to another address (a model profile's `destinations`, e.g. the
    C11's DZM to M); `options` records how the dialect was built (speed units, byte order)."""

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
        destinations: Mapping[str, str] | None = None,
    ) -> None:
        self.name = name
        self.title = title
        self.host_addresses = host_addresses
        self.headers = headers
        self.gimbal_header = gimbal_header
        self.options = dict(options or {})
        self.models: Mapping[str, DeviceModel] = {m.name: m for m in models}
        moved = dict(destinations or {})
        cmds: dict[str, CommandSpec] = {}
        roles: dict[str, list[CommandSpec]] = {}
        self._restrict: dict[str, frozenset[str] | None] = {}
        every_model = frozenset(self.models)
        for c in commands:
            if c.ident in cmds:
                raise ValueError(f"{name}: {c.ident} defined twice")
            if c.ident in moved:
                c = replace(c, address=moved.pop(c.ident))
            self._restrict[c.ident] = c.models
            supporting = frozenset(m.name for m in self.models.values() if self._allows(m, c.ident))
            support = None if supporting == every_model else supporting
            if support != c.models:  # most commands: no restriction either way, no copy to make
                c = replace(c, models=support)
            cmds[c.ident] = c
            if c.role:
                if c.role in roles and c.role not in MANY_ROLES:
                    raise ValueError(f"{name}: role {c.role!r} held by {roles[c.role][0].ident} and {c.ident}")
                roles.setdefault(c.role, []).append(c)
        if moved:
            raise ValueError(f"{name}: destinations for unknown commands {', '.join(sorted(moved))}")
        capacity = max(MAX_LENGTH[h] for h in headers)
        for c in cmds.values():
            for f in c.forms:
                if f.max_length > capacity:
                    raise ValueError(f"{name}: {c.ident} form {f.title!r} takes up to {f.max_length} bytes, "
                                     f"more than a {name} frame carries ({capacity})")  # fmt: skip
        self.commands: Mapping[str, CommandSpec] = cmds
        self._roles = roles
        self._by_name = {c.name: c for c in cmds.values()}
        for m in self.models.values():
            unknown = (m.commands or frozenset()) - cmds.keys()
            if unknown:
                raise ValueError(f"{name}: model {m.name} lists unknown commands {', '.join(sorted(unknown))}")
        # (ident, rw, direction) -> forms to try: the direction's own first, then the other
        # direction's, for frames whose addresses are not swapped (several document examples,
        # errata E5); and the same index for the decode hot path: identifier -> (spec, {control:
        # (forms of a request, forms of a response)}), each form with its length range and field
        # decoder. Filled per command on its first frame (`_hot_entry`): a short run (one
        # `topgimbal decode`) meets a few of the ~150 commands, and indexing them all at build
        # time was a large part of building a dialect.
        self._decode_index: dict[tuple[str, str, str], tuple[Form, ...]] = {}
        self._hot: dict[str, tuple[CommandSpec, dict[str, tuple[tuple[_HotForm, ...], ...]]]] = {}

    def __repr__(self) -> str:
        return f"<Dialect {self.name}: {len(self.commands)} commands, models {', '.join(self.models)}>"

    def _hot_entry(self, ident: str) -> tuple[CommandSpec, dict[str, tuple[tuple[_HotForm, ...], ...]]] | None:
        """`ident`'s decode index (see __init__), built now and kept; None for an unknown identifier.
        Two threads building it at once build equal entries: either one is kept."""
        c = self.commands.get(ident)
        if c is None:
            return None
        index = self._decode_index
        for rw in ("r", "w"):
            for direction, other in ((REQUEST, RESPONSE), (RESPONSE, REQUEST)):
                index[(ident, rw, direction)] = tuple(c.forms_for(rw, direction)) + tuple(c.forms_for(rw, other))
        by_rw = {
            rw: tuple(
                tuple((f, f.min_length, f.max_length, f.decoder) for f in index[(ident, rw, direction)])
                for direction in (REQUEST, RESPONSE)
            )
            for rw in ("r", "w")
        }
        by_rw[""] = by_rw["w"]  # a #Tp frame has no control character: decoded as a write
        entry = self._hot[ident] = (c, by_rw)
        return entry

    # -- lookup ------------------------------------------------------------------------------

    def command(self, ident: str) -> CommandSpec:
        """A command by identifier (any case) or by name."""
        spec = self.commands.get(ident) or self.commands.get(ident.upper()) or self._by_name.get(ident)
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

    def _allows(self, model: DeviceModel, ident: str) -> bool:
        restrict = self._restrict.get(ident)
        return model.supports(ident) and (restrict is None or model.name in restrict)

    def supports(self, model: str | DeviceModel, ident: str) -> bool:
        """Whether `model` (a name, or a profile, which may be a user's variant) has `ident`."""
        spec = self.commands.get(ident)
        if spec is None:
            return False
        if isinstance(model, DeviceModel):
            return self._allows(model, ident)
        return spec.models is None or model in spec.models

    def supported(self, model: str | DeviceModel) -> list[CommandSpec]:
        return [c for c in self.commands.values() if self.supports(model, c.ident)]

    def by_role(self, role: str, model: str | DeviceModel | None = None) -> CommandSpec | None:
        """The command that holds `role` (`ROLES`), among those `model` supports when given; None
        when there is none. For roles several commands hold (rate, angle...) the first one."""
        found = self.commands_with_role(role, model)
        return found[0] if found else None

    def require_role(self, role: str, model: str | DeviceModel | None = None) -> CommandSpec:
        """`by_role`, or UnsupportedError saying that this dialect / model has no such command."""
        spec = self.by_role(role, model)
        if spec is None:
            who = f"the {model if isinstance(model, str) else model.name}" if model is not None else f"{self.name}"
            raise UnsupportedError(f"{who} has no {role} command ({ROLES[role]})")
        return spec

    def commands_with_role(self, role: str, model: str | DeviceModel | None = None) -> list[CommandSpec]:
        if role not in ROLES:
            raise UnknownCommandError(f"{role!r} is not a role; known: {', '.join(ROLES)}")
        return [c for c in self._roles.get(role, ()) if model is None or self.supports(model, c.ident)]

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

    def _header(self, header: str | None, rw: str, spec: CommandSpec, n: int, dst: str) -> str:
        """The header to send: the caller's, checked against the dialect and the control, or ours."""
        if header is None:
            return self.header_for(spec, n, dst)
        if header not in self.headers:
            raise FieldValueError("header", header, f"one of {', '.join(self.headers)} in the {self.name} dialect")
        if header == NO_CONTROL_HEADER and rw != "w":
            raise FieldValueError(
                "header", header, "#TP, #tp or #tP for a query: a #Tp frame has no r/w control (it reads as a write)"
            )
        return header

    # -- encode --------------------------------------------------------------------------------

    def encode(
        self,
        ident: str,
        *,
        read: bool = False,
        src: str | None = None,
        dst: str | None = None,
        header: str | None = None,
        form: str | None = None,
        **values: Any,
    ) -> Frame:
        """The request frame for `ident` with field values in user units. `form` picks a form by
        title when several take the same field names (DZM's 2-, 4- and 6-character forms)."""
        spec = self.command(ident)
        rw = "r" if read else "w"
        chosen = spec.form(form, rw, REQUEST) if form is not None else spec.request_form(rw, values)
        data = chosen.encode(values, f"{spec.ident} ({'read' if read else 'write'})")
        dst = dst or spec.address
        hdr = self._header(header, rw, spec, len(data), dst)
        return make_frame(spec.ident, data, src=src or self.host_addresses[0], dst=dst, rw=rw, header=hdr)

    def response(self, request: Frame, *, rw: str | None = None, header: str | None = None, **values: Any) -> Frame:
        """The device's answer to `request` (addresses swapped) with field values in user units."""
        spec = self.command(request.ident)
        rw = rw or request.rw or "w"
        forms = spec.forms_for(rw, RESPONSE)
        if not forms:
            raise UnsupportedError(f"{spec.ident} has no {rw!r} response form in the {self.name} dialect")
        keys = values.keys()
        form = next((f for f in forms if keys <= f.names), forms[0])
        data = form.encode(values, f"{spec.ident} response")
        hdr = self._header(header, rw, spec, len(data), request.dst)
        return make_frame(spec.ident, data, src=request.dst, dst=request.src, rw=rw, header=hdr)

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
        form = next((f for f in forms if keys <= f.names and f.fields), None)
        if form is None:
            raise UnsupportedError(f"{spec.ident} has no matching device -> host form in the {self.name} dialect")
        data = form.encode(values, f"{spec.ident} report")
        src = src or spec.address
        hdr = self._header(header, form.rw, spec, len(data), src)
        return make_frame(spec.ident, data, src=src, dst=dst, rw=form.rw, header=hdr)

    # -- decode --------------------------------------------------------------------------------

    def decode(self, frame: Frame) -> Message:
        """Name the fields of `frame` in user units (never raises; `error` says what did not fit)."""
        return self.decoder()(frame)

    def decoder(self) -> Callable[[Frame], Message]:
        """The decoder behind `decode`: the C fast path's (built on first use, the same results) or
        `_decode_py`. It becomes this dialect's `decode`, so later calls go straight to it, and
        `FrameParser.feed_messages(data, dialect.decode)` decodes inside the C scan."""
        dec = self.__dict__.get("decode")
        if dec is None:
            dec = _speedups.make_decoder(self, Message, self._decode_py) or self._decode_py
            self.__dict__["decode"] = dec
        return dec

    def _decode_py(self, frame: Frame) -> Message:
        """Dialect.decode in pure Python (the reference the fast path is tested against). A frame no
        form takes costs little more than one that decodes: its error is worded only when read."""
        hot = self._hot.get(frame[4]) or self._hot_entry(frame[4])
        if hot is not None:
            per_direction = hot[1].get(frame[3])
            if per_direction is not None:
                data = frame[5]
                n = len(data)
                wrong = None
                # frame.src in DEVICE_ADDRESSES and frame.dst in HOST_ADDRESSES: a response
                hot_forms = per_direction[frame[1] in "MDEG" and frame[2] in "UP"]
                for form, lo, hi, decoder in hot_forms:
                    if lo <= n <= hi:
                        try:
                            return _new_tuple(Message, (frame, hot[0], form, decoder(data), None, self.name))
                        except ValueError:
                            wrong = wrong or form
                if wrong is not None:  # a form of the right length, wrong content: the first says what
                    error = LazyText(partial(_content_error, hot[0], wrong, data))
                elif hot_forms:
                    forms = tuple(f[0] for f in hot_forms)
                    error = LazyText(partial(_length_error, hot[0], frame[3] or "w", forms, n))
                else:
                    return self._decode_explained(frame)
                return _new_tuple(Message, (frame, hot[0], None, None, error, self.name))
        return self._decode_explained(frame)

    def _decode_explained(self, frame: Frame) -> Message:
        """Dialect.decode, every case with its error text (what the hot path above falls back to)."""
        spec = self.commands.get(frame.ident)
        if spec is None:
            return _new_tuple(
                Message, (frame, None, None, None, f"{frame.ident!r} is not in the {self.name} catalog", self.name)
            )
        if frame.ident not in self._hot:
            self._hot_entry(frame.ident)
        direction = RESPONSE if frame.src in DEVICE_ADDRESSES and frame.dst in HOST_ADDRESSES else REQUEST
        rw = frame.rw or "w"
        data = frame.data
        forms = self._decode_index.get((frame.ident, rw, direction))
        if forms is None:
            return _new_tuple(
                Message,
                (frame, spec, None, None, f"unknown form: control {rw!r} (a frame's control is r or w)", self.name),
            )
        if not forms:
            return _new_tuple(
                Message, (frame, spec, None, None, f"unknown form: {spec.ident} has no {rw!r} form", self.name)
            )
        wrong: Form | None = None
        for form in forms:
            if form.accepts_length(len(data)):
                try:
                    return _new_tuple(Message, (frame, spec, form, form.decoder(data), None, self.name))
                except ValueError:
                    wrong = wrong or form
        # Worded only when read (LazyText): a capture of unusual traffic must not pay for every text.
        if wrong is not None:  # a form of the right length, wrong content: the first says what it lacks
            return _new_tuple(
                Message, (frame, spec, None, None, LazyText(partial(_content_error, spec, wrong, data)), self.name)
            )
        error = LazyText(partial(_length_error, spec, rw, forms, len(data)))
        return _new_tuple(Message, (frame, spec, None, None, error, self.name))

    def check_values(self, model: DeviceModel, ident: str, values: Mapping[str, Any]) -> None:
        """Raise if `model` does not support `ident` or a value is outside the model's limits."""
        if not self.supports(model, ident):
            raise UnsupportedError(f"the {model.name} does not support {ident} ({self.command(ident).title})")
        for (lim_ident, fname), (lo, hi) in model.limits.items():
            value = values.get(fname)
            if (
                lim_ident == ident
                and isinstance(value, (int, float))
                and not isinstance(value, bool)
                and not lo <= value <= hi
            ):
                raise FieldValueError(fname, value, f"{lo:g}..{hi:g} on the {model.name}")


def _content_error(spec: CommandSpec, form: Form, data: bytes) -> str:
    """What `form` finds wrong with `data` (the field, its bytes, what it takes)."""
    try:
        form.decode(data)
    except ValueError as exc:
        return f"{spec.ident}: {exc}"
    return (
        f"{spec.ident}: {data!r} does not fit {form.title or 'its form'}"  # pragma: no cover - decoder and decode agree
    )


def _length_error(spec: CommandSpec, rw: str, forms: tuple[Form, ...], n: int) -> str:
    lengths = " or ".join(
        f"{f.min_length}" + (f"..{f.max_length}" if f.max_length != f.min_length else "") for f in forms
    )
    return f"{n} data bytes; {spec.ident} ({rw}) takes {lengths}"


__all__ = ["Dialect"]
