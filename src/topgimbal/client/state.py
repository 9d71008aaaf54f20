"""What the client last heard from the device: typed values with the time they arrived."""

from __future__ import annotations

import time
from dataclasses import asdict, dataclass, field
from typing import Any


@dataclass(frozen=True)
class Attitude:
    """Gimbal attitude in the API convention (degrees; yaw right-, pitch up-, roll right-positive).
    `t` is the monotonic arrival time, `wall` the wall-clock time."""

    yaw_deg: float
    pitch_deg: float
    roll_deg: float
    t: float = 0.0
    wall: float = 0.0
    source: str = "GAC"

    def as_dict(self) -> dict[str, Any]:
        return asdict(self)


@dataclass(frozen=True)
class SdCard:
    present: bool
    remaining_mb: int | None
    total_mb: int | None

    def as_dict(self) -> dict[str, Any]:
        return asdict(self)


@dataclass(frozen=True)
class Stamped:
    """A value and when it arrived (monotonic `t`, wall-clock `wall`)."""

    value: Any
    t: float
    wall: float


@dataclass
class StateCache:
    """Last known device state. Each entry is None until the device has said something about it."""

    attitude: Attitude | None = None
    zoom: Stamped | None = None  # optical magnification (x) or digital zoom
    recording: Stamped | None = None  # bool
    sd: Stamped | None = None  # SdCard
    range_m: Stamped | None = None  # float, or None value when the rangefinder failed
    version: Stamped | None = None
    model_name: Stamped | None = None
    temperature: Stamped | None = None
    mode: Stamped | None = None  # "follow" / "lock" as last commanded
    extra: dict[str, Stamped] = field(default_factory=dict)

    def set(self, name: str, value: Any) -> None:
        stamped = Stamped(value, time.monotonic(), time.time())
        if name in self.__dataclass_fields__ and name not in ("attitude", "extra"):
            setattr(self, name, stamped)
        else:
            self.extra[name] = stamped

    def as_dict(self) -> dict[str, Any]:
        def plain(v: Any) -> Any:
            if hasattr(v, "as_dict"):
                return v.as_dict()
            return v

        out: dict[str, Any] = {"attitude": self.attitude.as_dict() if self.attitude else None}
        for name in ("zoom", "recording", "sd", "range_m", "version", "model_name", "temperature", "mode"):
            s: Stamped | None = getattr(self, name)
            out[name] = None if s is None else {"value": plain(s.value), "t": s.t, "wall": s.wall}
        out["extra"] = {k: {"value": plain(s.value), "t": s.t, "wall": s.wall} for k, s in self.extra.items()}
        return out
