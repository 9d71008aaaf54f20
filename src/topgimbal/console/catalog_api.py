"""The model's commands with their field metadata, as JSON for the page.

The page builds its controls from this (enum tables become selects, ranges become inputs) and
disables what the model lacks, with the reason; nothing about a command is hand-coded twice."""

from __future__ import annotations

from typing import Any

from ..protocol import CommandSpec, DeviceModel, Dialect


def _jsonable(value: Any) -> Any:
    if value is None or isinstance(value, (bool, int, float, str)):
        return value
    if isinstance(value, bytes):
        return value.decode("latin-1")
    if isinstance(value, (list, tuple)):
        return [_jsonable(v) for v in value]
    if isinstance(value, dict):
        return {str(k): _jsonable(v) for k, v in value.items()}
    return str(value)


def command_json(spec: CommandSpec) -> dict[str, Any]:
    """The catalog's own description of the command (codecs give kinds, ranges, steps, tables)."""
    return _jsonable(spec.describe())  # type: ignore[no-any-return]


def model_json(model: DeviceModel) -> dict[str, Any]:
    return {
        "name": model.name,
        "title": model.title,
        "dialect": model.dialect,
        "thermal": model.thermal,
        "visible_lenses": model.visible_lenses,
        "optical_zoom_max": model.optical_zoom_max,
        "digital_zoom_max": model.digital_zoom_max,
        "lrf_range_m": list(model.lrf_range_m) if model.lrf_range_m else None,
        "yaw_range_deg": list(model.yaw_range_deg),
        "pitch_range_deg": list(model.pitch_range_deg),
        "roll_range_deg": list(model.roll_range_deg),
        "max_rate_deg_s": model.max_rate_deg_s,
        "endpoints": [str(e) for e in model.endpoints],
        "notes": model.notes,
    }


def unsupported_reason(dialect: Dialect, model: DeviceModel, ident: str) -> str | None:
    """Why `model` cannot use `ident` (None when it can)."""
    spec = dialect.commands.get(ident)
    if spec is None:
        return f"the {dialect.title} protocol has no {ident} command"
    if not dialect.supports(model, ident):
        others = ", ".join(sorted(spec.models or ())) or "no model"
        return f"the {model.name} does not support {ident} ({spec.title}); {spec.section} lists it for {others}"
    return None


def catalog_json(dialect: Dialect, model: DeviceModel) -> dict[str, Any]:
    supported = {c.ident: command_json(c) for c in dialect.supported(model)}
    unsupported = {
        c.ident: {"id": c.ident, "title": c.title, "reason": unsupported_reason(dialect, model, c.ident)}
        for c in dialect.commands.values()
        if c.ident not in supported
    }
    return {
        "dialect": dialect.name,
        "dialect_title": dialect.title,
        "model": model_json(model),
        "commands": supported,
        "unsupported": unsupported,
    }
