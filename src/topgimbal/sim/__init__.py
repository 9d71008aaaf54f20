"""The virtual camera: every model of both dialects over UDP, TCP and serial (or a pty), with
gimbal physics, camera and thermal state, a rangefinder, persistence, faults and device quirks.

Layers: `physics` (pure gimbal), `state` / `scene` (camera and world), `context` (what handlers
see), `handlers` (what each identifier does, and the handler table per dialect), `entries` /
`streams` / `quirks` (per-model dispatch, subscriptions, quirk switches from the profile), `device`
(sans-I/O core), `faults`, `servers` (asyncio transports) and `simulator` (the object users start).
See docs/simulator.md."""

from __future__ import annotations

from .background import BackgroundSimulator
from .clock import FakeClock, MonotonicClock
from .device import Device
from .faults import FaultInjector, FaultPlan, FaultPlanError
from .quirks import QUIRKS
from .simulator import Simulator

__all__ = [
    "QUIRKS",
    "BackgroundSimulator",
    "Device",
    "FakeClock",
    "FaultInjector",
    "FaultPlan",
    "FaultPlanError",
    "MonotonicClock",
    "Simulator",
]
