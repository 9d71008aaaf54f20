"""The virtual camera: every model of both dialects over UDP, TCP and serial (or a pty), with
gimbal physics, camera and thermal state, a rangefinder, persistence, faults and device quirks.

Layers: `physics` (pure gimbal), `state` / `scene` (camera and world), `handlers` (what each
identifier does, dispatched on the catalog), `device` (sans-I/O core), `faults`, `servers` (asyncio
transports) and `simulator` (the object users start). See docs/simulator.md."""

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
