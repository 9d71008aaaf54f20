"""Shorthands the dialect tables are written with (data stays data; these only cut repetition).

A table row is `command(ident=..., name=..., title=..., address=..., section=..., role=...,
group=..., write=[fields], read=[fields], ...)`, keyword-only: a row reads as what it is."""

from __future__ import annotations

from collections.abc import Iterable
from typing import TYPE_CHECKING, Any, TypedDict

from ..commands import CommandSpec
from ..fields import Codec, Field, FieldValue, HexInt
from ..forms import QUERY, REQUEST, RESPONSE, Form

if TYPE_CHECKING:
    from typing import Unpack  # Python 3.11; the protocol core still imports on 3.10

__all__ = [
    "QUERY",
    "F",
    "Place",
    "angle",
    "attitude_fields",
    "command",
    "level",
    "place",
    "rate",
    "report",
    "request",
    "write_forms",
]


class Place(TypedDict):
    """Where a run of table rows goes: destination address class and console group."""

    address: str
    group: str


def place(address: str, group: str) -> Place:
    return {"address": address, "group": group}


class FieldOptions(TypedDict, total=False):
    """Field's metadata keywords, as the command tables pass them to F()."""

    axis: str | None
    sign: int
    sign_kind: str | None
    state_key: str | None
    factory: FieldValue


def F(  # noqa: N802
    name: str, codec: Codec, description: str = "", default: FieldValue = None, **kw: Unpack[FieldOptions]
) -> Field:
    return Field(name, codec, description, default, **kw)


def angle(name: str, lo: float, hi: float, description: str = "", *, gimbal: bool = True) -> Field:
    """A signed 16-bit hex angle in 0.01 deg. A gimbal angle (`yaw_deg`...) carries its axis and
    the `angle` sign kind, so the model's wire signs apply to it."""
    axis = name.split("_", 1)[0] if gimbal else None
    codec = HexInt(4, signed=True, scale=0.01, unit="deg", min=lo, max=hi)
    return Field(name, codec, description, axis=axis, sign_kind="angle" if gimbal else None)


def attitude_fields(what: str = "gimbal", state: str | None = None) -> tuple[Field, ...]:
    """Yaw, pitch, roll as signed 16-bit hex in 0.01 deg, as on the wire (no sign changes here).
    Vehicle attitude (FAI) is not a gimbal axis: model wire signs do not apply to it. `state`
    prefixes the client state keys (`attitude` -> `attitude.yaw_deg`)."""
    g = what == "gimbal"
    out = []
    for axis in ("yaw", "pitch", "roll"):
        name = f"{axis}_deg"
        out.append(
            Field(
                name,
                HexInt(4, signed=True, scale=0.01, unit="deg", min=-327.68, max=327.67),
                f"{what} {axis}",
                axis=axis if g else None,
                sign_kind="attitude" if g else None,
                state_key=f"{state}.{name}" if state else None,
            )
        )
    return tuple(out)


def rate(axis: str, unit_deg_s: float, steps: int, description: str = "") -> Field:
    """A gimbal rate: signed 8-bit hex steps of `unit_deg_s`, +-`steps`."""
    codec = HexInt(2, signed=True, scale=unit_deg_s, unit="deg/s", min=-steps * unit_deg_s, max=steps * unit_deg_s)
    text = f"{axis} rate, -{steps}..{steps} steps" + (f"; {description}" if description else "")
    return Field(f"{axis}_rate_deg_s", codec, text, axis=axis, sign_kind="rate")


def level(name: str, hi: int = 100, description: str = "", unit: str = "", factory: FieldValue = None) -> Field:
    return Field(name, HexInt(2, max=hi, unit=unit), description, factory=factory)


def write_forms(fields: Iterable[Field], title: str = "set / control", *, section: str = "") -> list[Form]:
    """A write and its echo (the device's copy with addresses swapped)."""
    w = tuple(fields)
    return [
        Form("w", REQUEST, w, title=title, section=section),
        Form("w", RESPONSE, w, title=f"echo of {title}" if title != "set / control" else "echo", role="echo",
             section=section),
    ]  # fmt: skip


def command(
    *,
    ident: str,
    name: str,
    title: str,
    address: str,
    section: str,
    role: str,
    group: str,
    write: Iterable[Field] | None = None,
    read: Iterable[Field] | None = None,
    read_request: Form | None = None,
    extra_forms: Iterable[Form] = (),
    echo_fields: Iterable[Field] | None = None,
    **kw: Any,
) -> CommandSpec:
    """A command with the usual shape: a write that the device echoes, and/or a query (`00`)
    answered with `read` fields, plus any other forms."""
    forms: list[Form] = []
    if write is not None:
        w = tuple(write)
        forms.append(Form("w", REQUEST, w, title="set / control"))
        forms.append(
            Form("w", RESPONSE, tuple(echo_fields) if echo_fields is not None else w, title="echo", role="echo")
        )
    if read is not None:
        forms.append(read_request or QUERY)
        forms.append(Form("r", RESPONSE, tuple(read), title="answer"))
    forms.extend(extra_forms)
    return CommandSpec(
        ident=ident,
        name=name,
        title=title,
        address=address,
        forms=tuple(forms),
        section=section,
        role=role,
        group=group,
        **kw,
    )


def report(*fields: Field, rw: str = "w", title: str = "report", section: str = "") -> Form:
    """A device -> host form (unsolicited reports and alternative answers)."""
    return Form(rw, RESPONSE, tuple(fields), title=title, section=section)


def request(*fields: Field, rw: str = "w", title: str = "", section: str = "") -> Form:
    return Form(rw, REQUEST, tuple(fields), title=title, section=section)
