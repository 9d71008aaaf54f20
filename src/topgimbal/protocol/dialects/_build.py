"""Shorthands the dialect tables are written with (data stays data; these only cut repetition)."""

from __future__ import annotations

from collections.abc import Iterable
from typing import Any

from ..catalog import REQUEST, RESPONSE, CommandSpec, Form
from ..fields import Codec, Field, HexInt

QUERY = Form("r", REQUEST, const=b"00", title="query")


def F(name: str, codec: Codec, description: str = "", default: Any = None, **kw: Any) -> Field:  # noqa: N802
    return Field(name, codec, description, default, **kw)


def angle(name: str, lo: float, hi: float, description: str = "", *, gimbal: bool = True) -> Field:
    """A signed 16-bit hex angle in 0.01 deg. A gimbal angle (`yaw_deg`...) carries its axis, so
    the model's wire signs apply to it."""
    axis = name.split("_", 1)[0] if gimbal else None
    return Field(name, HexInt(4, signed=True, scale=0.01, unit="deg", min=lo, max=hi), description, axis=axis)


def attitude_fields(what: str = "gimbal") -> tuple[Field, ...]:
    """Yaw, pitch, roll as signed 16-bit hex in 0.01 deg, as on the wire (no sign changes here).
    Vehicle attitude (FAI) is not a gimbal axis: model wire signs do not apply to it."""
    g = what == "gimbal"
    return (
        angle("yaw_deg", -327.68, 327.67, f"{what} yaw", gimbal=g),
        angle("pitch_deg", -327.68, 327.67, f"{what} pitch", gimbal=g),
        angle("roll_deg", -327.68, 327.67, f"{what} roll", gimbal=g),
    )


def level(name: str, hi: int = 100, description: str = "", unit: str = "") -> Field:
    return Field(name, HexInt(2, max=hi, unit=unit), description)


def spec(
    ident: str,
    name: str,
    title: str,
    address: str,
    section: str,
    *,
    write: Iterable[Field] | None = None,
    read: Iterable[Field] | None = None,
    read_request: Form | None = None,
    extra_forms: Iterable[Form] = (),
    echo_fields: Iterable[Field] | None = None,
    **kw: Any,
) -> CommandSpec:
    """A command with the usual shape: a write that the device echoes, and/or a query (`00`)
    answered with `read` fields."""
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
    return CommandSpec(ident, name, title, address, tuple(forms), section, **kw)


def report(*fields: Field, rw: str = "w", title: str = "report") -> Form:
    """A device -> host form (unsolicited reports and alternative answers)."""
    return Form(rw, RESPONSE, tuple(fields), title=title)


def request(*fields: Field, rw: str = "w", title: str = "") -> Form:
    return Form(rw, REQUEST, tuple(fields), title=title)
