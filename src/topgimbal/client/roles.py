"""Which catalog command plays which role for the client, and what the client keeps from each frame.

The one place in the client that knows facts the catalog does not state yet as metadata (a command's
role, a field's state key, acknowledgements that differ from the data sent, answers whose length
character is known to be wrong). Everything is derived from the catalog's structure or keyed by
identifier and field name: no branch on a dialect's name. When the catalog gains `role` /
`state_key` metadata, this module is the only one to change.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from typing import Any

from ..errors import FieldValueError, UnsupportedError
from ..protocol import CommandSpec, DeviceModel, Dialect, Frame, Message

# -- roles -----------------------------------------------------------------------------------------

# role -> (candidate identifiers, a field the read answer must have)
ROLES: dict[str, tuple[tuple[str, ...], str]] = {
    "version": (("VER", "VSN"), "version"),
    "model_name": (("PA2",), "model"),
    "sd_card": (("SDC",), ""),
    "attitude": (("GAC",), "yaw_deg"),
    "attitude_earth": (("GIC",), "yaw_deg"),
    "attitude_stream": (("GAA",), ""),
    "range_query": (("SLR",), "distance_m"),
    "rangefinder": (("LRF",), ""),
    "optical_zoom": (("MUL",), "magnification_x"),
    "digital_zoom": (("DZM",), ""),
    "altitude": (("ALT",), ""),
}

# What `detect_model()` assumes when a probe is answered and the dialect has several models.
DETECTED_MODEL = {"PA2": "SIP", "VER": "C12", "VSN": "SIP"}

# Frames that report the gimbal's attitude (answers and streams look alike).
ATTITUDE_IDENTS = frozenset({"GAC", "GIC", "GIA"})

# Answers whose length character real firmware gets wrong (the checksum still covers the data):
# a real C12 answers VER with length 3 and 6 data characters. Other frames the parser had to
# recover are not trusted as answers (a truncated frame can pass an 8-bit checksum).
RECOVERED_LENGTH_OK = frozenset({"VER"})

# Idents whose query answers are what the device reads, not what it was told: the attitude.
TELEMETRY_IDENTS = ATTITUDE_IDENTS


def _read_fields(spec: CommandSpec) -> set[str]:
    return {f.name for form in spec.forms_for("r", "response") for f in form.fields}


def role_ident(dialect: Dialect, model: DeviceModel, role: str) -> str | None:
    """The identifier that plays `role` on `model`, or None when the model has none."""
    candidates, needs = ROLES[role]
    for ident in candidates:
        spec = dialect.commands.get(ident)
        if spec is None or not dialect.supports(model, ident):
            continue
        if needs and needs not in _read_fields(spec):
            continue
        return ident
    return None


def require_role(dialect: Dialect, model: DeviceModel, role: str, what: str) -> str:
    ident = role_ident(dialect, model, role)
    if ident is None:
        raise UnsupportedError(f"the {model.name} has no {what}")
    return ident


def ping_ident(dialect: Dialect, model: DeviceModel) -> str | None:
    """A harmless query every model of the dialect answers (the link check)."""
    for role in ("version", "model_name", "attitude", "sd_card"):
        ident = role_ident(dialect, model, role)
        if ident is not None and dialect.commands[ident].readable:
            return ident
    return None


# -- layouts that differ between dialects ------------------------------------------------------------


def sd_card_queries(spec: CommandSpec) -> list[dict[str, Any]]:
    """The SDC queries to send: one answer with both figures, or one query per figure."""
    request_fields = {f.name for form in spec.forms_for("r", "request") for f in form.fields}
    if "which" in request_fields:
        return [{"which": "remaining"}, {"which": "total"}]
    return [{}]


def sd_card_figures(answers: Sequence[Mapping[str, Any]]) -> tuple[bool, int | None, int | None]:
    """(present, remaining_mb, total_mb) from the answers to `sd_card_queries`."""
    if len(answers) == 1:
        total, remaining = answers[0].get("total_mb"), answers[0].get("remaining_mb")
        return bool(total), (remaining if total else None), (total or None)
    remaining, total = answers[0].get("capacity_mb"), answers[1].get("capacity_mb")
    return remaining is not None and total is not None, remaining, total


def stream_values(spec: CommandSpec, rate_hz: float | None) -> dict[str, Any]:
    """The attitude-stream command's values for `rate_hz` (None: off). Rate-controlled streams
    take 1..100 Hz; on/off streams run at the device's own rate."""
    fields = {f.name for form in spec.forms_for("w", "request") for f in form.fields}
    if "rate_hz" in fields:
        if rate_hz is None:
            return {"rate_hz": 0}
        rate = round(rate_hz)
        if not 1 <= rate <= 100:
            raise FieldValueError("rate_hz", rate_hz, "1..100 Hz")
        return {"rate_hz": rate}
    return {"state": "off" if rate_hz is None else "on"}


def digital_zoom_values(
    spec: CommandSpec, model: DeviceModel, level_or_action: str | float, lens: str
) -> dict[str, Any]:
    """DZM values: per-lens 0.1x levels and steps, or whole levels 1..4x and steps."""
    fields = {f.name for form in spec.forms_for("w", "request") for f in form.fields}
    value: Any = level_or_action
    words = isinstance(value, str) and not is_number_text(value)
    if "lens" in fields:
        value = {"in": "step_in", "out": "step_out"}.get(value, value) if words else float(value)
        return {"lens": lens, "zoom": value}
    if words:
        return {"zoom": {"in": "zoom_in", "out": "zoom_out"}.get(value, value)}
    f = float(value)
    if f != int(f) or not 1 <= f <= 4:
        raise FieldValueError("zoom", level_or_action, f"1, 2, 3 or 4 (x) on the {model.name}")
    return {"zoom": f"{int(f)}x"}


def is_number_text(text: str) -> bool:
    try:
        float(text)
    except ValueError:
        return False
    return True


# -- names users type --------------------------------------------------------------------------------

FOCUS_ALIASES = {"plus": "focus_plus", "+": "focus_plus", "minus": "focus_minus", "-": "focus_minus"}
ZOOM_ALIASES = {"in": "zoom_in", "out": "zoom_out"}
THERMAL_ALIASES = {"palette": "IMG", "scene": "TSM", "shutter": "TAS", "range": "TMR"}


def enum_names(spec: CommandSpec, field: str) -> list[str]:
    for form in spec.forms_for("w", "request"):
        for f in form.fields:
            if f.name == field:
                return [v.name for v in getattr(f.codec, "values", ())]
    return []


def focus_actions(dialect: Dialect) -> list[str]:
    """What `focus()` and `topgimbal focus` accept: the short aliases, then the catalog's names."""
    names = enum_names(dialect.command("FCC"), "action")
    short = [a for a, full in FOCUS_ALIASES.items() if full in names and a.isalpha()]
    return short + [n for n in names if n not in FOCUS_ALIASES.values()]


def thermal_ident(dialect: Dialect, setting: str) -> str:
    ident = THERMAL_ALIASES.get(setting)
    if ident is not None:
        return ident
    for spec in dialect.commands.values():
        if spec.name in (setting, f"thermal_{setting}") or spec.ident == setting.upper():
            return spec.ident
    known = [
        *THERMAL_ALIASES,
        *(s.name.removeprefix("thermal_") for s in dialect.commands.values() if s.name.startswith("thermal_")),
    ]
    raise FieldValueError("setting", setting, "one of " + ", ".join(dict.fromkeys(known)))


# -- acknowledgements ---------------------------------------------------------------------------------

# A write whose acknowledgement is a report rather than a copy of the data sent (TOPOTEK REC and
# CAP answer with the new state and a file index): request field -> {request value: acceptable
# report states}. `None` as request value: any.
ACK_REPORTS: dict[str, tuple[str, Mapping[Any, frozenset[str]]]] = {
    "REC": (
        "action",
        {
            "start": frozenset({"started", "recording"}),
            "stop": frozenset({"stopped"}),
            "toggle": frozenset({"started", "recording", "stopped"}),
        },
    ),
    "CAP": ("mode", {None: frozenset({"taken"})}),
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


def echo_matches(request: Frame, request_fields: Mapping[str, Any] | None, reply: Message) -> bool:
    """Whether `reply` acknowledges the write `request`: the same data (whatever its length, hex
    case aside), or for the commands in ACK_REPORTS a report stating the requested outcome."""
    if reply.frame.data.upper() == request.data.upper():
        return True
    rule = ACK_REPORTS.get(request.ident)
    if rule is None or reply.fields is None or not is_report(reply):
        return False
    field, outcomes = rule
    wanted = outcomes.get((request_fields or {}).get(field), outcomes.get(None))
    return wanted is not None and reply.fields.get("state") in wanted


# -- the state cache: identifier -> what it tells ---------------------------------------------------


@dataclass(frozen=True)
class StateRule:
    key: str
    value: Callable[[Message], Any]  # returns _SKIP when the frame says nothing about `key`
    reads_only: bool = False


_SKIP = object()


def _field(*names: str, convert: Callable[[Any], Any] = lambda v: v) -> Callable[[Message], Any]:
    def get(m: Message) -> Any:
        f = m.fields or {}
        for n in names:
            if n in f:
                return convert(f[n])
        return _SKIP

    return get


def _recording(value: Any) -> Any:
    if value in ("recording", "started", "start"):
        return True
    if value in ("stopped", "stop"):
        return False
    return _SKIP


def _sd(m: Message) -> Any:
    f = m.fields or {}
    if "total_mb" not in f:
        return _SKIP  # one figure per answer: sd_card() puts the two together
    from .state import SdCard

    present, remaining, total = sd_card_figures([f])
    return SdCard(present, remaining, total)


STATE_RULES: dict[str, StateRule] = {
    "REC": StateRule("recording", _field("state", "action", convert=_recording)),
    "SDC": StateRule("sd", _sd),
    "ZMP": StateRule("zoom", _field("magnification_x")),
    "MUL": StateRule("zoom", _field("magnification_x")),
    "DZM": StateRule("zoom", _field("zoom", "visible_zoom_x"), reads_only=True),
    "LRF": StateRule("range_m", _field("distance_m")),
    "SLR": StateRule("range_m", _field("distance_m")),
    "VER": StateRule("version", _field("version")),
    "VSN": StateRule("version", _field("version")),
    "PA2": StateRule("model_name", _field("model")),
    "TMP": StateRule("temperature", lambda m: m.fields if m.fields else _SKIP),
    "CAP": StateRule("last_photo_index", _field("file_index")),
}


def state_updates(message: Message) -> list[tuple[str, Any]]:
    """(state key, value) pairs that `message` (decoded, API convention) tells."""
    rule = STATE_RULES.get(message.frame.ident)
    if rule is None or message.fields is None or (rule.reads_only and message.frame.rw != "r"):
        return []
    value = rule.value(message)
    return [] if value is _SKIP else [(rule.key, value)]
