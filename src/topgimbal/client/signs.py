"""The client's side of the sign convention: decoded messages and outgoing values mapped through
`protocol.signs` (the same code the simulator uses), so the API is always degrees, yaw
right-positive, pitch up-positive, whatever the device's wire says."""

from __future__ import annotations

from collections.abc import Mapping

from ..protocol import CommandSpec, Message
from ..protocol.signs import AXES, flip, negated_fields, resolve_signs

__all__ = ["AXES", "MessageSigns", "map_message", "map_values", "resolve_signs"]

MAX_SPECS = 1024  # commands remembered by a MessageSigns (a dialect has about 150)


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


class MessageSigns:
    """`map_message` with one client's signs, each command's negated fields worked out once: most
    commands on most models negate nothing (every C12 attitude sample), and their messages pass as
    they are, without a copy of their fields."""

    __slots__ = ("_negates", "signs")  # one per client, read per frame

    def __init__(self, signs: Mapping[str, int]) -> None:
        self.signs = signs
        self._negates: dict[str, tuple[CommandSpec, bool]] = {}  # ident -> (its spec, negates a field)

    def __call__(self, message: Message) -> Message:
        spec = message.spec
        if message.fields is None or spec is None or not spec.signed_fields:
            return message
        known = self._negates.get(spec.ident)
        if known is None or known[0] is not spec:  # a spec of another dialect under the same ident
            if len(self._negates) >= MAX_SPECS:
                self._negates.clear()
            known = self._negates[spec.ident] = (spec, bool(negated_fields(spec, self.signs)))
        return map_message(message, self.signs) if known[1] else message
