"""What acknowledges a write: the same data, or where the model's profile says so (`echo_rules`), a
report that states the requested outcome. Pure functions over decoded messages; the engine calls
`EchoPolicy.matches` for every write's candidate acknowledgement."""

from __future__ import annotations

from collections.abc import Mapping

from ..protocol import DeviceModel, Frame, Message

# What a report acknowledging a write must say, by the command's catalog role: request field ->
# {request value: report states that show it was done}; `None` as request value: any request.
# The words are the catalog's enum names for the recording and photo commands.
OUTCOMES: dict[str, tuple[str, Mapping[object, frozenset[str]]]] = {
    "recording": (
        "action",
        {
            "start": frozenset({"started", "recording"}),
            "stop": frozenset({"stopped"}),
            "toggle": frozenset({"started", "recording", "stopped"}),
        },
    ),
    "photo": ("mode", {None: frozenset({"taken"})}),
}


def is_report(message: Message) -> bool:
    """A device -> host form that is neither a write's echo nor a query's (first) answer."""
    form, spec = message.form, message.spec
    if form is None or spec is None:
        return False
    if message.frame.rw == "w":
        return form.role != "echo"
    answers = spec.forms_for("r", "response")
    return bool(answers) and form is not answers[0]


class EchoPolicy:
    """`matches(request, request_fields, reply)`: whether `reply` acknowledges the write `request`."""

    def __init__(self, model: DeviceModel | None = None) -> None:
        self.rules: Mapping[str, str] = model.echo_rules if model is not None else {}

    def matches(self, request: Frame, request_fields: Mapping[str, object] | None, reply: Message) -> bool:
        """The same data (whatever its length, hex case aside), or for a command the profile's
        `echo_rules` name, a report of that form stating the requested outcome."""
        if reply.frame.data.upper() == request.data.upper():
            return True
        title = self.rules.get(request.ident)
        form, spec = reply.form, reply.spec
        if title is None or form is None or spec is None or form.title != title or reply.fields is None:
            return False
        rule = OUTCOMES.get(spec.role)
        if rule is None:
            return True  # the profile names the form; no outcome to compare
        field, outcomes = rule
        wanted = outcomes.get((request_fields or {}).get(field), outcomes.get(None))
        return wanted is not None and reply.fields.get("state") in wanted

    def __call__(self, request: Frame, request_fields: Mapping[str, object] | None, reply: Message) -> bool:
        return self.matches(request, request_fields, reply)


def needs_fields(model: DeviceModel, ident: str) -> bool:
    """Whether the engine needs a write's decoded values to judge its acknowledgement."""
    return ident in model.echo_rules
