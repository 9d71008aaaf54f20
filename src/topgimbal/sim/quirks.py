"""Quirk switches: a thin reader of the model profile. The names and what they mean are the
protocol's `QUIRKS`; which are on for a model is its profile's `quirks`; a caller turns any on or
off (`--quirks crlf,-ver_wrong_length`). A few take a value (`late_answers=30` answers slow queries
30 s late, `late_answers=never` never)."""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

from ..protocol import QUIRKS, DeviceModel

# Quirks that take a value, with its default when only switched on. None means "never".
PARAMETERS: dict[str, float | None] = {"late_answers": 120.0}
NEVER = ("never", "none")
Override = bool | float | None


def resolve(
    model: DeviceModel, overrides: Mapping[str, Override] | None = None
) -> tuple[dict[str, bool], dict[str, float | None]]:
    """The quirk switches for `model` (its profile's, then `overrides`), and the values of the
    quirks that take one."""
    on = model.quirk_defaults()
    values = dict(PARAMETERS)
    for name, value in (overrides or {}).items():
        if name not in QUIRKS:
            raise ValueError(f"unknown quirk {name!r}; known: {', '.join(QUIRKS)}")
        if isinstance(value, bool):
            on[name] = value
        elif name in PARAMETERS and (value is None or isinstance(value, (int, float))):
            on[name] = True
            values[name] = None if value is None else float(value)
        else:
            raise ValueError(f"quirk {name}: expected on / off{_value_hint(name)}, not {value!r}")
    return on, values


def _value_hint(name: str) -> str:
    return " or seconds / never" if name in PARAMETERS else ""


def parse(text: str) -> dict[str, Any]:
    """CLI form: `lowercase_header,crlf,-ver_wrong_length,late_answers=30` (a leading - or no-
    turns one off; NAME=on/off; a quirk that takes a value: NAME=SECONDS or NAME=never)."""
    out: dict[str, Any] = {}  # bool, or a quirk's value (seconds, None for never)
    for item in filter(None, (p.strip() for p in text.split(","))):
        name = item
        parsed: Override = True
        if item.startswith("-"):
            name, parsed = item[1:], False
        elif item.startswith("no-"):
            name, parsed = item[3:], False
        elif "=" in item:
            name, _, raw = item.partition("=")
            parsed = _value(name, raw.strip().lower(), item)
        if name not in QUIRKS:
            raise ValueError(f"unknown quirk {name!r}; known: {', '.join(QUIRKS)}")
        out[name] = parsed
    return out


def _value(name: str, raw: str, item: str) -> Override:
    if raw in ("1", "on", "true", "yes"):
        return True
    if raw in ("0", "off", "false", "no"):
        return False
    if name in PARAMETERS:
        if raw in NEVER:
            return None
        try:
            seconds = float(raw.removesuffix("s"))
        except ValueError:
            seconds = -1.0
        if seconds >= 0 and seconds == seconds and seconds != float("inf"):
            return seconds
    raise ValueError(f"quirk {item!r}: expected NAME, -NAME or NAME=on/off{_value_hint(name)}")


__all__ = ["NEVER", "PARAMETERS", "QUIRKS", "parse", "resolve"]
