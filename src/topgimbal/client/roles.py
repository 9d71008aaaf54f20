"""Which catalog command plays which role on the connected model, read from the catalog's metadata.

The catalog states what each command is for (`CommandSpec.role`, from the closed set
`protocol.ROLES`), which axes a motion command's fields move (`Field.axis`), and the model profile
says which commands the firmware ignores. This module only asks those questions: there is no
dialect name and no table of identifiers here. Where the two dialects lay a role out differently
(one SD card answer or one query per figure, rate-controlled or on/off streams), the layout is read
from the command's fields.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass

from ..errors import FieldValueError, UnsupportedError
from ..protocol import CommandSpec, DeviceModel, Dialect, Form

# -- roles ---------------------------------------------------------------------------------------


def command(dialect: Dialect, model: DeviceModel, role: str) -> CommandSpec | None:
    """The command that plays `role` on `model` (None: the model has none)."""
    return dialect.by_role(role, model)


def require(dialect: Dialect, model: DeviceModel, role: str, what: str) -> CommandSpec:
    """`command`, or UnsupportedError naming the model and what it lacks."""
    spec = dialect.by_role(role, model)
    if spec is None:
        raise UnsupportedError(f"the {model.name} has no {what}")
    return spec


def role_ident(dialect: Dialect, model: DeviceModel, role: str) -> str | None:
    spec = dialect.by_role(role, model)
    return None if spec is None else spec.ident


def require_role(dialect: Dialect, model: DeviceModel, role: str, what: str) -> str:
    return require(dialect, model, role, what).ident


def readable(dialect: Dialect, model: DeviceModel, role: str) -> CommandSpec | None:
    """The command of `role` if it can be queried."""
    spec = dialect.by_role(role, model)
    return spec if spec is not None and spec.readable else None


def ping_ident(dialect: Dialect, model: DeviceModel) -> str | None:
    """A harmless query the model answers quickly (the link check). Slow answers are no use."""
    for role in ("version", "attitude", "sd_capacity", "model_name"):
        spec = readable(dialect, model, role)
        if spec is not None and spec.ident not in model.slow_answers:
            return spec.ident
    return None


# Identity roles a device answers about itself, in the order worth asking.
IDENTITY_ROLES = ("model_name", "version", "hardware_version", "serial_number")


def identity_queries(dialect: Dialect, model: DeviceModel | None = None) -> list[tuple[str, CommandSpec]]:
    """(role, command) for each identity question the dialect (or `model`) can ask."""
    out = []
    for role in IDENTITY_ROLES:
        spec = dialect.by_role(role, model)
        if spec is not None and spec.readable:
            out.append((role, spec))
    return out


def answer_text(spec: CommandSpec, fields: Mapping[str, object]) -> str | None:
    """The text an identity answer carries (its one field with a state key, else its first)."""
    keyed = [name for name in spec.state_keys if name in fields]
    name = keyed[0] if keyed else next(iter(fields), None)
    value = None if name is None else fields.get(name)
    return None if value is None else str(value).strip()


# -- motion: commands by role and axes -------------------------------------------------------------


@dataclass(frozen=True)
class AxisCommand:
    """One motion frame to send: a command and its values (API units)."""

    spec: CommandSpec
    values: dict[str, object]


def _request_form(spec: CommandSpec) -> Form:
    return spec.forms_for("w", "request")[0]


def motion_plan(
    dialect: Dialect,
    model: DeviceModel,
    role: str,
    wanted: Mapping[str, float],
    *,
    combined: bool = True,
    speed_deg_s: float | None = None,
) -> list[AxisCommand]:
    """The frames that set `wanted` ({axis: value}) with commands of `role` (`rate`, `angle`,
    `earth_angle`): the fewest commands whose axes are all wanted (one axis per frame when not
    `combined`), never one the model's firmware ignores. UnsupportedError when an axis cannot be
    set that way."""
    candidates = [
        s
        for s in dialect.commands_with_role(role, model)
        if s.writable and s.axes and s.ident not in model.ignored and (combined or len(s.axes) == 1)
    ]
    candidates.sort(key=lambda s: -len(s.axes))
    left = dict(wanted)
    plan: list[AxisCommand] = []
    while left:
        spec = next((s for s in candidates if set(s.axes) <= left.keys()), None)
        if spec is None:
            axes = ", ".join(sorted(left))
            text = f"the {model.name} takes no {role.replace('_', ' ')} command for {axes}"
            ignored = sorted(s.ident for s in dialect.commands_with_role(role, model) if s.ident in model.ignored)
            if ignored:
                text += f" (its firmware ignores {', '.join(ignored)}"
                text += ": point() closes the loop over rate commands)" if role == "angle" else ")"
            raise UnsupportedError(text)
        values: dict[str, object] = {}
        for f in _request_form(spec).fields:
            if f.axis in left:
                values[f.name] = left[f.axis]
            elif speed_deg_s is not None and f.name.endswith("speed_deg_s"):
                values[f.name] = speed_deg_s
        for axis in spec.axes:
            left.pop(axis, None)
        plan.append(AxisCommand(spec, values))
    return plan


def can_move(dialect: Dialect, model: DeviceModel, role: str, axes: Sequence[str]) -> bool:
    """Whether commands of `role` the firmware obeys cover `axes` (one axis per frame)."""
    covered = {
        a
        for s in dialect.commands_with_role(role, model)
        if s.writable and s.ident not in model.ignored
        for a in s.axes
    }
    return set(axes) <= covered


def rate_limits(dialect: Dialect, model: DeviceModel, axis: str) -> tuple[float, float]:
    """(largest, smallest non-zero) rate in deg/s a single-axis rate command sends on `axis`."""
    for s in dialect.commands_with_role("rate", model):
        if s.axes == (axis,) and s.ident not in model.ignored:
            info = _request_form(s).fields[0].codec.describe()
            hi = min(float(info.get("max", model.max_rate_deg_s)), model.max_rate_deg_s)
            return hi, float(info.get("step") or 0.1)
    raise UnsupportedError(f"the {model.name} takes no rate command for {axis}")


# -- layouts that differ between dialects ------------------------------------------------------------


def _field_names(spec: CommandSpec, rw: str, direction: str) -> set[str]:
    return {f.name for form in spec.forms_for(rw, direction) for f in form.fields}


def sd_card_queries(spec: CommandSpec) -> list[dict[str, object]]:
    """The SD card queries to send: one answer with both figures, or one query per figure."""
    if "which" in _field_names(spec, "r", "request"):
        return [{"which": "remaining"}, {"which": "total"}]
    return [{}]


def sd_card_figures(answers: Sequence[Mapping[str, object]]) -> tuple[bool, int | None, int | None]:
    """(present, remaining_mb, total_mb) from the answers to `sd_card_queries`."""

    def mb(v: object) -> int | None:
        return int(v) if isinstance(v, (int, float)) else None

    if len(answers) == 1:
        total, remaining = mb(answers[0].get("total_mb")), mb(answers[0].get("remaining_mb"))
        return bool(total), (remaining if total else None), (total or None)
    remaining, total = mb(answers[0].get("capacity_mb")), mb(answers[1].get("capacity_mb"))
    return remaining is not None and total is not None, remaining, total


def stream_values(spec: CommandSpec, rate_hz: float | None) -> dict[str, object]:
    """The attitude-stream command's values for `rate_hz` (None: off). Rate-controlled streams
    take 1..100 Hz; on/off streams run at the device's own rate."""
    if "rate_hz" in _field_names(spec, "w", "request"):
        if rate_hz is None:
            return {"rate_hz": 0}
        rate = round(rate_hz)
        if not 1 <= rate <= 100:
            raise FieldValueError("rate_hz", rate_hz, "1..100 Hz")
        return {"rate_hz": rate}
    return {"state": "off" if rate_hz is None else "on"}


def digital_zoom_values(
    spec: CommandSpec, model: DeviceModel, level_or_action: str | float, lens: str
) -> dict[str, object]:
    """Digital zoom values: per-lens 0.1x levels and steps, or whole levels 1..4x and steps."""
    words = isinstance(level_or_action, str) and not is_number_text(level_or_action)
    if "lens" in _field_names(spec, "w", "request"):
        if words:
            action = str(level_or_action)
            return {"lens": lens, "zoom": {"in": "step_in", "out": "step_out"}.get(action, action)}
        return {"lens": lens, "zoom": float(level_or_action)}
    if words:
        action = str(level_or_action)
        return {"zoom": {"in": "zoom_in", "out": "zoom_out"}.get(action, action)}
    f = float(level_or_action)
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
# Short setting names of `thermal()` -> the catalog role of the command that holds them.
THERMAL_ROLES = {
    "palette": "palette",
    "scene": "thermal_scene",
    "shutter": "thermal_shutter",
    "range": "temperature_range",
}


def enum_names(spec: CommandSpec, field: str) -> list[str]:
    for form in spec.forms_for("w", "request"):
        for f in form.fields:
            if f.name == field:
                return [v.name for v in getattr(f.codec, "values", ())]
    return []


def focus_actions(dialect: Dialect) -> list[str]:
    """What `focus()` and `topgimbal focus` accept: the short aliases, then the catalog's names."""
    spec = dialect.by_role("focus_control")
    names = enum_names(spec, "action") if spec is not None else []
    short = [a for a, full in FOCUS_ALIASES.items() if full in names and a.isalpha()]
    return short + [n for n in names if n not in FOCUS_ALIASES.values()]


def thermal_ident(dialect: Dialect, model: DeviceModel, setting: str) -> str:
    role = THERMAL_ROLES.get(setting)
    if role is not None:
        spec = dialect.by_role(role, model) or dialect.by_role(role)
        if spec is not None:
            return spec.ident
    for spec in dialect.commands.values():
        if spec.name in (setting, f"thermal_{setting}") or spec.ident == setting.upper():
            return spec.ident
    known = [
        *THERMAL_ROLES,
        *(s.name.removeprefix("thermal_") for s in dialect.commands.values() if s.name.startswith("thermal_")),
    ]
    raise FieldValueError("setting", setting, "one of " + ", ".join(dict.fromkeys(known)))


# -- what the parser may have recovered ---------------------------------------------------------------


def recovered_ok(dialect: Dialect, model: DeviceModel) -> frozenset[str]:
    """Answers taken even when the parser had to recover their length character: the version
    answer of a model whose profile names the `ver_wrong_length` quirk (a real C12 answers with
    length 3 and 6 data characters; the checksum covers them). Other recovered frames are not
    trusted as answers: a truncated frame can pass an 8-bit checksum."""
    if "ver_wrong_length" not in model.quirks:
        return frozenset()
    spec = dialect.by_role("version", model)
    return frozenset() if spec is None else frozenset({spec.ident})
