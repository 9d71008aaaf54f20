"""How device commands print: `--json` for scripts, plain indented lines for people (no Python
reprs, `-` for nothing, times as dates)."""

from __future__ import annotations

import argparse
import datetime
import json

from ..client.jsonable import jsonable
from ..client.state import GimbalAttitude


def plain(value: object) -> object:
    """Client results as JSON-able values: the SDK's one encoding (`client/jsonable.py`, which the
    console and the Zenoh server share; NaN is null)."""
    return jsonable(value)


def show(args: argparse.Namespace, result: object) -> None:
    result = plain(result)
    if args.json:
        print(json.dumps(result, allow_nan=False))
        return
    for line in human(result):
        print(line)


def human(value: object, indent: str = "") -> list[str]:
    """Readable lines: nested mappings indented, no Python reprs (None, {...}), times as dates."""
    if isinstance(value, dict):
        out = []
        for k, v in value.items():
            if v is None and k in ("error",):
                continue  # "error: None" says nothing
            if isinstance(v, dict) and v:
                out.append(f"{indent}{k}:")
                out += human(v, indent + "  ")
            else:
                out.append(f"{indent}{k}: {text(k, v)}")
        return out
    return [] if value is None else [f"{indent}{text('', value)}"]


def text(key: str, v: object) -> str:
    if v is None:
        return "-"
    if isinstance(v, dict):
        return "-"
    if isinstance(v, (list, tuple)):
        return ", ".join(text("", x) for x in v) or "-"
    if key in ("t", "wall") and isinstance(v, float) and v > 1e9:
        return datetime.datetime.fromtimestamp(v).isoformat(sep=" ", timespec="milliseconds")
    if isinstance(v, float):
        return f"{v:g}"
    return str(v)


def attitude_dict(att: GimbalAttitude) -> dict[str, object]:
    return {"yaw_deg": att.yaw_deg, "pitch_deg": att.pitch_deg, "roll_deg": att.roll_deg, "t": att.wall}


def ok(action: str, **extra: object) -> dict[str, object]:
    return {"ok": True, "action": action, **extra}
