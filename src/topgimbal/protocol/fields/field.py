"""A named field of a form: a codec plus what the field means."""

from __future__ import annotations

from dataclasses import dataclass
from typing import TypedDict

from .base import Codec, CodecDescription, FieldValue, JsonScalar


class _FieldKeys(TypedDict):
    name: str
    description: str
    default: JsonScalar
    axis: str | None
    sign_kind: str | None
    state_key: str | None
    factory: JsonScalar


class FieldDescription(_FieldKeys, CodecDescription):
    """`Field.describe()`: the field's own keys, then its codec's."""


AXES = ("yaw", "pitch", "roll")
# What kind of quantity a gimbal-axis field is: models may put a different wire sign on each
# (the C12 reports GAY's yaw sign opposite to GSY's; C11/C13 invert GSY yaw only).
SIGN_KINDS = {
    "angle": "an angle set-point (GAY, GIP, GAM ...)",
    "rate": "a rate command (GSY, GSM, RPS, YPR ...)",
    "attitude": "an attitude report (GAC, GIC, the GIA stream ...)",
}


@dataclass(frozen=True)
class Field:
    """A named field of a form: the codec plus its description.

    - `default`: the value used when a caller omits the field (None: required);
    - `factory`: the value a stored setting holds on a new device (the simulator's factory state;
      None: the codec's neutral value, see `factory_values`);
    - `state_key`: where a client's state cache keeps the last value heard (`"version"`,
      `"sd.remaining_mb"`, `"zoom.optical_x"`...); None: not cached under a shared name.

    Sign metadata (read by the client and the simulator through `protocol.signs`, nowhere else):
    `axis` names the gimbal axis an angle or rate field measures and `sign_kind` which kind of
    quantity it is (`SIGN_KINDS`), so the device model's wire signs apply to it; `sign` is a fixed
    wire sign for fields whose document states their own convention (TOPOTEK UAV pitch is
    down-positive: -1)."""

    name: str
    codec: Codec
    description: str = ""
    default: FieldValue = None
    axis: str | None = None
    sign: int = 1
    sign_kind: str | None = None
    state_key: str | None = None
    factory: FieldValue = None

    def __post_init__(self) -> None:
        if self.axis is not None:
            if self.axis not in AXES:
                raise ValueError(f"field {self.name}: axis {self.axis!r} is not one of {', '.join(AXES)}")
            if self.sign_kind is None:
                object.__setattr__(self, "sign_kind", "angle")
        if self.sign_kind is not None and self.sign_kind not in SIGN_KINDS:
            raise ValueError(f"field {self.name}: sign_kind {self.sign_kind!r} is not one of {', '.join(SIGN_KINDS)}")
        if self.sign not in (1, -1):
            raise ValueError(f"field {self.name}: sign must be 1 or -1")

    @property
    def unit(self) -> str:
        return self.codec.unit

    def describe(self) -> FieldDescription:
        return {
            "name": self.name,
            "description": self.description,
            "default": self.codec.to_json(self.default),
            "axis": self.axis,
            "sign_kind": self.sign_kind,
            "state_key": self.state_key,
            "factory": self.codec.to_json(self.factory),
            **self.codec.describe(),
        }


__all__ = ["AXES", "SIGN_KINDS", "Field", "FieldDescription"]
