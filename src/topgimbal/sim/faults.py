"""The fault plan: seeded damage to the simulator's incoming and outgoing traffic.

`FaultPlan` is the description (what the CLI's `--faults` and a JSON file give);
`FaultInjector` applies it to one direction of traffic. The injector is pure: it takes a packet
(a datagram or a write to a byte stream) and the current time and returns what to deliver when,
so the same plan and seed always damage the same packets in the same way.
"""

from __future__ import annotations

import json
import math
import random
from collections.abc import Hashable
from dataclasses import dataclass, field, fields
from pathlib import Path
from typing import Any

from ..inputfile import InputFileError, load_json

MAX_PLAN_FILE_BYTES = 1024 * 1024  # a fault plan is a few lines
PROBABILITIES = ("drop", "duplicate", "corrupt", "truncate", "reorder", "late_reply_p")
DURATIONS = ("delay_s", "jitter_s", "late_reply_s", "reorder_hold_s")
DIRECTIONS = ("both", "in", "out")


class FaultPlanError(ValueError):
    """A fault plan that cannot be used; the message names the key and what is allowed."""


@dataclass(frozen=True)
class FaultPlan:
    """Probabilities are 0..1 per packet; durations in seconds.

    - drop: the packet vanishes.  duplicate: it is delivered twice.
    - corrupt: one random bit of one random byte is flipped (a flipped checksum makes the
      receiver drop the frame, as a device drops bad checksums).  truncate: it is cut short.
    - delay_s + jitter_s: every packet is held delay_s plus a uniform 0..jitter_s.
    - reorder: the packet is held back and delivered after the next one (or after
      reorder_hold_s if none comes).
    - late_reply_s: replies to requests (not streams) are held this long, with probability
      late_reply_p (default 1): a client sees them after its timeout.
    - silence: windows (start_s, end_s), in seconds since the simulator started, in which nothing
      passes in the affected direction(s).
    - direction: "out" (device -> host), "in" (host -> device) or "both".
    """

    drop: float = 0.0
    duplicate: float = 0.0
    corrupt: float = 0.0
    truncate: float = 0.0
    delay_s: float = 0.0
    jitter_s: float = 0.0
    reorder: float = 0.0
    late_reply_s: float = 0.0
    silence: tuple[tuple[float, float], ...] = ()
    direction: str = "both"
    late_reply_p: float = 1.0
    reorder_hold_s: float = 0.2

    def __post_init__(self) -> None:
        for name in PROBABILITIES:
            v = getattr(self, name)
            if not isinstance(v, (int, float)) or isinstance(v, bool) or not 0.0 <= v <= 1.0 or math.isnan(v):
                raise FaultPlanError(f"fault {name}={v!r}: expected a probability 0..1")
        for name in DURATIONS:
            v = getattr(self, name)
            if not isinstance(v, (int, float)) or isinstance(v, bool) or not 0.0 <= v < 3600 or math.isnan(v):
                raise FaultPlanError(f"fault {name}={v!r}: expected seconds, 0 or more (under an hour)")
        if self.direction not in DIRECTIONS:
            raise FaultPlanError(f"fault direction={self.direction!r}: expected one of {', '.join(DIRECTIONS)}")
        windows = []
        for w in self.silence:
            try:
                a, b = (float(x) for x in w)
            except (TypeError, ValueError):
                raise FaultPlanError(f"silence window {w!r}: expected (start_s, end_s)") from None
            if not 0 <= a < b:
                raise FaultPlanError(f"silence window {w!r}: expected 0 <= start_s < end_s")
            windows.append((a, b))
        object.__setattr__(self, "silence", tuple(windows))

    @property
    def active(self) -> bool:
        return self != FaultPlan(direction=self.direction)

    def applies_to(self, direction: str) -> bool:
        return self.direction in ("both", direction)

    # -- parsing -------------------------------------------------------------------------------

    @classmethod
    def keys(cls) -> list[str]:
        return [f.name for f in fields(cls)]

    @classmethod
    def from_dict(cls, data: dict[str, Any]) -> FaultPlan:
        unknown = sorted(set(data) - set(cls.keys()))
        if unknown:
            raise FaultPlanError(f"unknown fault {unknown[0]!r}; allowed: {', '.join(cls.keys())}")
        values = dict(data)
        if "silence" in values:
            values["silence"] = tuple(tuple(w) for w in values["silence"])
        return cls(**values)

    @classmethod
    def parse(cls, text: str) -> FaultPlan:
        """`"drop=0.3,corrupt=0.1,delay_s=0.05,silence=2-3;5-6,direction=out"`, or `@plan.json`
        / a path ending in .json for the JSON form (an object with the same keys)."""
        text = text.strip()
        if text.startswith("@") or text.endswith(".json"):
            return cls.load(text.lstrip("@"))
        if text.startswith("{"):
            try:
                return cls.from_dict(json.loads(text))
            except json.JSONDecodeError as exc:
                raise FaultPlanError(f"fault plan JSON: {exc}") from None
        values: dict[str, Any] = {}
        for item in filter(None, (p.strip() for p in text.split(","))):
            key, sep, raw = item.partition("=")
            key = key.strip()
            if not sep:
                raise FaultPlanError(f"fault {item!r}: expected KEY=VALUE; keys: {', '.join(cls.keys())}")
            if key not in set(cls.keys()):
                raise FaultPlanError(f"unknown fault {key!r}; allowed: {', '.join(cls.keys())}")
            raw = raw.strip()
            if key == "direction":
                values[key] = raw
            elif key == "silence":
                values[key] = tuple(_window(w) for w in raw.split(";") if w.strip())
            else:
                try:
                    values[key] = float(raw.rstrip("%")) / (100.0 if raw.endswith("%") else 1.0)
                except ValueError:
                    raise FaultPlanError(f"fault {key}={raw!r}: expected a number") from None
        return cls.from_dict(values)

    @classmethod
    def load(cls, path: str | Path) -> FaultPlan:
        try:  # a regular file (not /dev/zero, not a FIFO), bounded, its JSON nesting bounded
            data = load_json(path, MAX_PLAN_FILE_BYTES, "fault plan file")
        except InputFileError as exc:
            raise FaultPlanError(str(exc)) from None
        if not isinstance(data, dict):
            raise FaultPlanError(f"fault plan file {path}: expected a JSON object with keys {', '.join(cls.keys())}")
        return cls.from_dict(data)

    def to_dict(self) -> dict[str, Any]:
        d = {f.name: getattr(self, f.name) for f in fields(self)}
        d["silence"] = [list(w) for w in self.silence]
        return d


def _window(text: str) -> tuple[float, float]:
    a, sep, b = text.strip().partition("-")
    try:
        if not sep:
            raise ValueError
        return float(a), float(b)
    except ValueError:
        raise FaultPlanError(f"silence window {text!r}: expected START-END in seconds, e.g. 2-3.5") from None


@dataclass(order=True)
class Scheduled:
    """A packet to deliver at `at` (ordered by time, then by arrival for stability)."""

    at: float
    seq: int
    dest: Hashable = field(compare=False)
    data: bytes = field(compare=False)


class FaultInjector:
    """Applies a plan to one direction ("in" or "out") of traffic, deterministically per seed."""

    def __init__(self, plan: FaultPlan, direction: str, rng: random.Random, start: float) -> None:
        self.plan = plan
        # Fixed for the injector's life: a disabled one passes every packet through and never holds
        # one, so the simulator skips asking it what is due (per stream frame, in a fleet).
        self.enabled = plan.applies_to(direction) and plan.active
        self.rng = rng
        self.start = start
        self._seq = 0
        self._queue: list[Scheduled] = []
        self._held: Scheduled | None = None
        self.counts: dict[str, int] = {
            k: 0 for k in ("drop", "duplicate", "corrupt", "truncate", "reorder", "late", "silence")
        }

    def silent(self, now: float) -> bool:
        t = now - self.start
        return any(a <= t < b for a, b in self.plan.silence)

    def submit(self, dest: Hashable, data: bytes, now: float, *, reply: bool = False) -> list[tuple[Hashable, bytes]]:
        """Take one packet; return what is due now (the rest waits for `due()`)."""
        if not self.enabled:
            return [(dest, data)]
        p, rng = self.plan, self.rng
        # Draw every random number in a fixed order whatever the outcome, so that one packet's
        # fate does not shift the fates of the packets after it between otherwise equal runs.
        r_drop, r_dup, r_cor, r_trunc, r_reord, r_late, r_jit = (rng.random() for _ in range(7))
        bit, cut = rng.random(), rng.random()
        if self.silent(now):
            self.counts["silence"] += 1
            return self.due(now)
        if r_drop < p.drop:
            self.counts["drop"] += 1
            return self.due(now)
        if r_cor < p.corrupt and data:
            self.counts["corrupt"] += 1
            i = int(bit * len(data) * 8)
            b = bytearray(data)
            b[i // 8] ^= 1 << (i % 8)
            data = bytes(b)
        if r_trunc < p.truncate and len(data) > 1:
            self.counts["truncate"] += 1
            data = data[: 1 + int(cut * (len(data) - 1))]
        at = now + p.delay_s + r_jit * p.jitter_s
        if reply and p.late_reply_s > 0 and r_late < p.late_reply_p:
            self.counts["late"] += 1
            at += p.late_reply_s
        copies = 2 if r_dup < p.duplicate else 1
        if copies == 2:
            self.counts["duplicate"] += 1
        for _ in range(copies):
            self._seq += 1
            item = Scheduled(at, self._seq, dest, data)
            if self._held is None and r_reord < p.reorder:
                # Hold this one back: it goes out after the next packet (or after a while).
                self.counts["reorder"] += 1
                item.at = at + p.reorder_hold_s
                self._held = item
                continue
            self._queue.append(item)
            if self._held is not None and self._held is not item:
                held, self._held = self._held, None
                held.at = max(at, min(held.at, at))
                self._seq += 1
                held.seq = self._seq
                self._queue.append(held)
        self._queue.sort()
        return self.due(now)

    def due(self, now: float) -> list[tuple[Hashable, bytes]]:
        if self._held is not None and self._held.at <= now:
            self._queue.append(self._held)
            self._held = None
            self._queue.sort()
        out = []
        while self._queue and self._queue[0].at <= now + 1e-9:
            item = self._queue.pop(0)
            out.append((item.dest, item.data))
        return out

    def next_due(self) -> float | None:
        times = [q.at for q in self._queue[:1]]
        if self._held is not None:
            times.append(self._held.at)
        return min(times) if times else None

    def forget(self, dest: Hashable) -> None:
        """Drop what is queued for a peer that went away (a closed TCP connection)."""
        self._queue = [q for q in self._queue if q.dest != dest]
        if self._held is not None and self._held.dest == dest:
            self._held = None
