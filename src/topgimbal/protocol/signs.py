"""One sign convention for users, each device's on the wire.

The API convention: degrees, yaw right-positive, pitch up-positive, roll right-positive. The
catalog holds values as on the wire; which fields carry a sign, and whose convention, is field
metadata (`Field.axis`: a gimbal axis, so the model's `wire_signs` apply; `Field.sign`: a fixed
convention a document states for that field). The client and the simulator both map through here,
so the two ends of a link can never disagree about a sign. The map is its own inverse."""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

from ..errors import FieldValueError
from .catalog import CommandSpec, DeviceModel

AXES = ("yaw", "pitch", "roll")


def resolve_signs(model: DeviceModel, override: Mapping[str, int] | None = None) -> dict[str, int]:
    """The model's wire signs with a user's per-axis overrides (`{"pitch": -1}`), validated."""
    signs = {axis: int(model.wire_signs.get(axis, 1)) for axis in AXES}
    for axis, sign in (override or {}).items():
        if axis not in AXES:
            raise FieldValueError("signs", axis, f"an axis name: {', '.join(AXES)}")
        if sign not in (1, -1):
            raise FieldValueError(f"signs[{axis!r}]", sign, "1 or -1")
        signs[axis] = sign
    return signs


def flip(spec: CommandSpec, values: Mapping[str, Any], signs: Mapping[str, int]) -> dict[str, Any]:
    """API values <-> wire values for `spec` (the same operation both ways)."""
    out = dict(values)
    for name, axis, fixed in spec.signed_fields:
        sign = signs.get(axis, 1) if axis else fixed
        v = out.get(name)
        if sign == -1 and isinstance(v, (int, float)) and not isinstance(v, bool):
            out[name] = -v + 0.0  # + 0.0: never "-0.0"
    return out
