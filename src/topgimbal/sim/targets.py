"""Targets in the simulated world: small objects that move across the sphere of directions around
the camera (bearing / elevation, earth frame) and can be hidden for intervals (occlusion). Pure:
a target's place is a function of the time since the simulator started.

A target is given on the command line as `key=value` pairs (`sim --target
"bearing=10,elevation=-5,speed=10,heading=0,size=1.5,hide=3-3.5"`) or as a JSON file holding an
object or a list of objects with the same keys. Keys (defaults in TARGET_DEFAULTS):

- `name`: how the truth file and the picture call it (t1, t2... by default);
- `bearing`, `elevation`: where it is at time 0 (degrees, earth frame);
- `speed` (deg/s) and `heading` (degrees: 0 moves right, towards growing bearing; 90 moves up);
- `span`: when > 0 the target goes back and forth over this many degrees instead of on for ever;
- `size`: its angular diameter (degrees); `contrast`: 0..1, how dark it is against the scene in
  the visible picture; `temp`: its temperature (°C) in the thermal one (hot by default);
- `hide`: intervals `START-END` (seconds since start) joined by `+`, when it is occluded.
"""

from __future__ import annotations

import json
import math
from collections.abc import Iterable, Sequence
from dataclasses import dataclass
from typing import Any

from ..errors import InputError
from ..geo.earth import wrap180
from ..inputfile import InputFileError, load_json

MAX_TARGETS = 16  # a scene is for tracking tests, not crowds; each target costs a draw per frame
MAX_HIDE_INTERVALS = 64
MAX_SPEC_FILE_BYTES = 1 << 20
TARGET_DEFAULTS: dict[str, float] = {
    "bearing": 0.0,
    "elevation": 0.0,
    "speed": 0.0,
    "heading": 0.0,
    "span": 0.0,
    "size": 1.5,
    "contrast": 0.8,
    "temp": 60.0,
}


class TargetSpecError(InputError, ValueError):
    """A target description that cannot be used (unknown key, bad number, too many targets)."""


@dataclass(frozen=True)
class Target:
    name: str
    bearing_deg: float
    elevation_deg: float
    speed_deg_s: float = 0.0
    heading_deg: float = 0.0
    span_deg: float = 0.0
    size_deg: float = 1.5
    contrast: float = 0.8
    temp_c: float = 60.0
    hidden: tuple[tuple[float, float], ...] = ()

    def travelled_deg(self, t_s: float) -> float:
        """Distance along the path at time t (back and forth over `span` when it is set)."""
        d = self.speed_deg_s * max(0.0, t_s)
        if self.span_deg > 0:
            period = 2.0 * self.span_deg
            d = d % period
            d = d if d <= self.span_deg else period - d
        return d

    def at(self, t_s: float) -> tuple[float, float]:
        """(bearing, elevation) in degrees at time t; bearing wrapped to [-180, 180), elevation
        kept within +-89 (a path over the zenith is not modelled)."""
        d = self.travelled_deg(t_s)
        h = math.radians(self.heading_deg)
        el = max(-89.0, min(89.0, self.elevation_deg + d * math.sin(h)))
        # Along a parallel, a degree of arc is 1/cos(el) degrees of bearing: speed is true angular speed.
        az = self.bearing_deg + d * math.cos(h) / max(0.05, math.cos(math.radians(el)))
        return wrap180(az), el

    def visible(self, t_s: float) -> bool:
        return not any(a <= t_s < b for a, b in self.hidden)


@dataclass(frozen=True)
class TargetView:
    """One target at one moment: what the renderer, the tracker and the truth file read."""

    name: str
    bearing_deg: float
    elevation_deg: float
    size_deg: float
    contrast: float
    temp_c: float
    visible: bool


def views(targets: Sequence[Target], t_s: float) -> tuple[TargetView, ...]:
    out = []
    for tg in targets:
        az, el = tg.at(t_s)
        out.append(TargetView(tg.name, az, el, tg.size_deg, tg.contrast, tg.temp_c, tg.visible(t_s)))
    return tuple(out)


def _number(key: str, text: object) -> float:
    if isinstance(text, bool):  # JSON's true is no bearing of 1 degree
        raise TargetSpecError(f"target {key}: expected a number, got {json.dumps(text)}")
    try:
        v = float(text)  # type: ignore[arg-type]
    except (TypeError, ValueError):
        raise TargetSpecError(f"target {key}: expected a number, got {text!r}") from None
    if not math.isfinite(v):
        raise TargetSpecError(f"target {key}: expected a finite number, got {text!r}")
    return v


def _hidden(value: object) -> tuple[tuple[float, float], ...]:
    if isinstance(value, str):
        items: list[Any] = [p.split("-", 1) for p in value.split("+") if p.strip()]
    elif isinstance(value, list):
        items = list(value)
    else:
        raise TargetSpecError(f"target hide: expected START-END[+START-END...], got {value!r}")
    if len(items) > MAX_HIDE_INTERVALS:
        raise TargetSpecError(f"target hide: at most {MAX_HIDE_INTERVALS} intervals")
    out = []
    for item in items:
        if not isinstance(item, (list, tuple)) or len(item) != 2:
            raise TargetSpecError(f"target hide: expected START-END, got {item!r}")
        a, b = _number("hide", item[0]), _number("hide", item[1])
        if not 0 <= a < b:
            raise TargetSpecError(f"target hide: expected 0 <= START < END, got {a:g}-{b:g}")
        out.append((a, b))
    return tuple(sorted(out))


def target_from(values: dict[str, Any], index: int) -> Target:
    """A target from its keys (the command line's or a JSON object's)."""
    unknown = set(values) - set(TARGET_DEFAULTS) - {"name", "hide"}
    if unknown:
        known = ", ".join(["name", "hide", *TARGET_DEFAULTS])
        raise TargetSpecError(f"target: unknown key(s) {', '.join(sorted(unknown))} (known: {known})")
    v = {k: _number(k, values.get(k, d)) for k, d in TARGET_DEFAULTS.items()}
    if not -90 < v["elevation"] < 90:
        raise TargetSpecError(f"target elevation: expected -90 < elevation < 90, got {v['elevation']:g}")
    if not 0 <= v["speed"] <= 360:
        raise TargetSpecError(f"target speed: expected 0..360 deg/s, got {v['speed']:g}")
    if not 0.05 <= v["size"] <= 45:
        raise TargetSpecError(f"target size: expected 0.05..45 degrees, got {v['size']:g}")
    if not 0 <= v["contrast"] <= 1:
        raise TargetSpecError(f"target contrast: expected 0..1, got {v['contrast']:g}")
    if not 0 <= v["span"] <= 360:
        raise TargetSpecError(f"target span: expected 0..360 degrees, got {v['span']:g}")
    if not -40 <= v["temp"] <= 500:
        raise TargetSpecError(f"target temp: expected -40..500 °C, got {v['temp']:g}")
    name = str(values.get("name") or f"t{index + 1}")
    if len(name) > 32 or not name.isprintable():
        raise TargetSpecError(f"target name: expected up to 32 printable characters, got {name!r}")
    return Target(
        name,
        v["bearing"],
        v["elevation"],
        v["speed"],
        v["heading"],
        v["span"],
        v["size"],
        v["contrast"],
        v["temp"],
        _hidden(values.get("hide", [])),
    )


def parse_spec(text: str, index: int = 0) -> Target:
    """One target from `key=value,key=value...`."""
    values: dict[str, Any] = {}
    for part in text.split(","):
        if not part.strip():
            continue
        key, sep, value = part.partition("=")
        if not sep:
            raise TargetSpecError(f"target: expected key=value, got {part.strip()!r}")
        values[key.strip()] = value.strip()
    return target_from(values, index)


def load(items: Iterable[str]) -> tuple[Target, ...]:
    """Targets from `--target` values: each a spec, or the path of a JSON file (an object or a
    list of objects) when it names a file (ends in .json or contains no '=')."""
    out: list[Target] = []
    for item in items:
        if "=" in item and not item.endswith(".json"):
            out.append(parse_spec(item, len(out)))
            continue
        try:  # a regular file only (/dev/zero, a FIFO: refused), bounded, nesting bounded
            data = load_json(item, MAX_SPEC_FILE_BYTES, "target file")
        except InputFileError as exc:
            raise TargetSpecError(str(exc)) from None
        for obj in data if isinstance(data, list) else [data]:
            if not isinstance(obj, dict):
                raise TargetSpecError(f"target file {item}: expected objects, got {type(obj).__name__}")
            out.append(target_from(obj, len(out)))
        if len(out) > MAX_TARGETS:
            break
    if len(out) > MAX_TARGETS:
        raise TargetSpecError(f"at most {MAX_TARGETS} targets (got more)")
    names = [t.name for t in out]
    if len(set(names)) != len(names):
        raise TargetSpecError(f"target names must differ (got {', '.join(names)})")
    return tuple(out)
