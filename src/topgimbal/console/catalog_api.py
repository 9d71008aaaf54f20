"""The model's commands with their field metadata, as JSON for the page.

The page builds its controls from this (enum tables become selects, ranges become inputs) and
disables what the model lacks, with the reason; nothing about a command is hand-coded twice.

Presentation is added here, not in the catalog: every field gets an English `label` (the catalog's
own when it has one, else made from its name), every enum value an English `label` and, when
the vendor document names it in Chinese, its `vendor_term` (the catalog's own when it has one,
else split off a mixed label such as "White hot 白热"). Reasons never carry vendor section
numbers; those go in `section`, which the page shows as a tooltip.
"""

from __future__ import annotations

import unicodedata
from typing import Any

from ..client.jsonable import jsonable
from ..protocol import GROUPS, CommandSpec, DeviceModel, Dialect

_UNIT_SUFFIXES = ("deg_s", "m_s", "deg", "mb", "kbps", "hz", "px", "c", "s", "m", "x")
_WORDS = {
    "lat": "latitude",
    "lon": "longitude",
    "alt": "altitude",
    "temp": "temperature",
    "pos": "position",
    "avg": "average",
    "h": "horizontal",
    "v": "vertical",
}
_ACRONYMS = {"uid", "osd", "led", "fps", "gop", "ip", "dns", "sd", "utc", "gps"}


def field_label(name: str) -> str:
    """An English label from a field name: `interval_s` -> "Interval", `avg_temp_c` -> "Average
    temperature", `h_flip` -> "Horizontal flip" (the unit is shown next to it by the page)."""
    words = name.split("_")
    for suffix in _UNIT_SUFFIXES:
        tail = suffix.split("_")
        if len(words) > len(tail) and words[-len(tail) :] == tail:
            words = words[: -len(tail)]
            break
    out = [w.upper() if w in _ACRONYMS else _WORDS.get(w, w) for w in words if w]
    text = " ".join(out) or name
    return text[:1].upper() + text[1:]


def _is_cjk(ch: str) -> bool:
    return unicodedata.east_asian_width(ch) in ("W", "F") and unicodedata.category(ch).startswith(("L", "P"))


def split_label(label: str) -> tuple[str, str | None]:
    """("White hot", "白热") from "White hot 白热": the English part and the vendor's term, split at
    the first CJK character; (label, None) when there is none."""
    for i, ch in enumerate(label):
        if _is_cjk(ch):
            head, term = label[:i].rstrip(), label[i:].strip()
            if head.endswith(("(", "（")):  # "Centre (回中)"
                head, term = head[:-1], term.rstrip(")）")
            return head.strip(" /-"), term.strip() or None
    return label, None


def _present_value(value: dict[str, Any]) -> dict[str, Any]:
    out = dict(value)
    label = str(out.get("label") or out.get("name") or "")
    if out.get("vendor_term"):
        english = split_label(label)[0]
    else:
        english, term = split_label(label)
        if term:
            out["vendor_term"] = term
    out["label"] = english or field_label(str(out.get("name", "")))
    return out


def _present_field(field: dict[str, Any]) -> dict[str, Any]:
    out = dict(field)
    if "name" in out and not out.get("label"):
        out["label"] = field_label(str(out["name"]))
    for key in ("values", "tokens"):
        if isinstance(out.get(key), list):
            out[key] = [_present_value(v) if isinstance(v, dict) else v for v in out[key]]
    return out


def command_json(spec: CommandSpec) -> dict[str, Any]:
    """The catalog's own description of the command (codecs give kinds, ranges, steps, tables),
    with English labels and vendor terms for the page."""
    desc: dict[str, Any] = jsonable(spec.describe())  # type: ignore[assignment]
    for form in desc.get("forms", []):
        form["fields"] = [_present_field(f) for f in form.get("fields", [])]
    return desc


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


def dialect_label(dialect: Dialect) -> str:
    """An English name for the dialect ("SkyDroid TOP protocol"); the vendor document's own title
    (in Chinese for SkyDroid) is `dialect.title`, which the page keeps for a tooltip."""
    return f"{dialect.title.split()[0]} TOP protocol"


def unsupported_reason(dialect: Dialect, model: DeviceModel, ident: str) -> str | None:
    """Why `model` cannot use `ident` (None when it can)."""
    spec = dialect.commands.get(ident)
    if spec is None:
        return f"the {dialect_label(dialect)} has no {ident} command"
    if not dialect.supports(model, ident):
        others = ", ".join(sorted(spec.models or ()))
        have = f"; only the {others} {'has' if len(spec.models or ()) == 1 else 'have'} it" if others else ""
        return f"the {model.name} does not support {ident} ({spec.title}){have}"
    return None


def catalog_json(dialect: Dialect, model: DeviceModel) -> dict[str, Any]:
    supported = {c.ident: command_json(c) for c in dialect.supported(model)}
    unsupported = {
        c.ident: {
            "id": c.ident,
            "title": c.title,
            "reason": unsupported_reason(dialect, model, c.ident),
            "section": c.section,
            "role": c.role,
            "group": c.group,
        }
        for c in dialect.commands.values()
        if c.ident not in supported
    }
    return {
        "dialect": dialect.name,
        "dialect_title": dialect.title,
        "dialect_label": dialect_label(dialect),
        "model": model_json(model),
        "groups": dict(GROUPS),
        "commands": supported,
        "unsupported": unsupported,
    }
