"""The client's side of the sign convention: decoded messages and outgoing values mapped through
`protocol.signs` (the same code the simulator uses), so the API is always degrees, yaw
right-positive, pitch up-positive, whatever the device's wire says."""

from __future__ import annotations

from collections.abc import Mapping

from ..protocol import CommandSpec, Message
from ..protocol.signs import AXES, flip, resolve_signs

__all__ = ["AXES", "map_message", "map_values", "resolve_signs"]


def map_values(spec: CommandSpec, values: Mapping[str, object], signs: Mapping[str, int]) -> dict[str, object]:
    """API values -> wire values for `spec` (the mapping is its own inverse)."""
    return flip(spec, values, signs)


def map_message(message: Message, signs: Mapping[str, int]) -> Message:
    """A decoded wire message with its signed fields in the API convention."""
    if message.fields is None or message.spec is None or not message.spec.signed_fields:
        return message
    # Positionally (fields is the 4th; new ones are only appended): _replace costs twice as much,
    # and this runs for every attitude sample.
    return Message._make((*message[:3], flip(message.spec, message.fields, signs), *message[4:]))
