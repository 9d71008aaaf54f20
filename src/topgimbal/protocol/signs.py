"""One sign convention for users, each device's on the wire.

The API convention: degrees, yaw right-positive, pitch up-positive, roll right-positive. The
catalog holds values as on the wire; which fields carry a sign, and whose convention, is field
metadata: `Field.axis` with `Field.sign_kind` (an angle set-point, a rate command or an attitude
report: the model's wire signs apply) or `Field.sign` (a fixed convention a document states for that
field). The client and the simulator both map through here, so the two ends of a link can never
disagree about a sign. The map is its own inverse.

Signs are resolved once per connection into a flat table with an entry per axis and one per kind
and axis (`"yaw"`, `"rate.yaw"`, ...). Resolution order, later wins:

    1. the model's axis entries      wire_signs={"pitch": -1}        every kind of pitch
    2. the model's kind entries      wire_signs={"rate.yaw": -1}     only yaw rate commands
    3. the user's axis overrides     {"yaw": 1}                      every kind of yaw, model's kinds too
    4. the user's kind overrides     {"angle.yaw": -1}               only that kind
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

from ..errors import FieldValueError
from .commands import CommandSpec
from .fields import AXES, SIGN_KINDS
from .models import DeviceModel

KINDS = tuple(SIGN_KINDS)
SIGN_KEYS = (*AXES, *(f"{k}.{a}" for k in KINDS for a in AXES))


def _check(key: str, sign: object) -> None:
    if key not in SIGN_KEYS:
        raise FieldValueError("signs", key, f"an axis name ({', '.join(AXES)}) or kind.axis ({', '.join(KINDS)})")
    if isinstance(sign, bool) or sign not in (1, -1):
        raise FieldValueError(f"signs[{key!r}]", sign, "1 or -1")


def resolve_signs(model: DeviceModel, override: Mapping[str, int] | None = None) -> dict[str, int]:
    """The model's wire signs with a user's overrides (`{"pitch": -1}`, `{"rate.yaw": -1}`),
    validated, as the flat table `flip` reads: every key of `SIGN_KEYS`."""
    out = {key: 1 for key in SIGN_KEYS}
    layers = [
        {k: v for k, v in model.wire_signs.items() if k in AXES},
        {k: v for k, v in model.wire_signs.items() if k not in AXES},
    ]
    user = dict(override or {})
    for key, sign in user.items():
        _check(key, sign)
    layers += [{k: v for k, v in user.items() if k in AXES}, {k: v for k, v in user.items() if k not in AXES}]
    for layer in layers:
        for key, sign in layer.items():
            _check(key, sign)
            if key in AXES:
                out[key] = sign
                for kind in KINDS:
                    out[f"{kind}.{key}"] = sign
            else:
                out[key] = sign
    return out


def sign_of(signs: Mapping[str, int], kind: str, axis: str) -> int:
    """The wire sign of one kind of quantity on one axis, from a resolved (or a plain axis) table."""
    return signs.get(f"{kind}.{axis}", signs.get(axis, 1))


def flip(spec: CommandSpec, values: Mapping[str, Any], signs: Mapping[str, int]) -> dict[str, Any]:
    """API values <-> wire values for `spec` (the same operation both ways). `signs` is a table
    from `resolve_signs` (a plain `{"pitch": -1}` also works: axis entries cover every kind)."""
    out = dict(values)
    for name in negated_fields(spec, signs):
        v = out.get(name)
        if isinstance(v, (int, float)) and not isinstance(v, bool):
            out[name] = -v + 0.0  # + 0.0: never "-0.0"
    return out


def negated_fields(spec: CommandSpec, signs: Mapping[str, int]) -> tuple[str, ...]:
    """The fields of `spec` whose sign `flip` changes under `signs` (none: `flip` copies values)."""
    out: list[str] = []
    for name, key, axis, fixed in spec.wire_sign_fields:
        if axis:
            sign = signs.get(key)
            if sign is None:
                sign = signs.get(axis, 1)
        else:
            sign = fixed
        if sign == -1:
            out.append(name)
    return tuple(out)


__all__ = ["AXES", "KINDS", "SIGN_KEYS", "flip", "negated_fields", "resolve_signs", "sign_of"]
