"""The virtual camera: every model of both dialects over UDP, TCP and serial (or a pty), with
gimbal physics, camera and thermal state, a rangefinder, persistence, faults and device quirks.

Layers: `physics` (pure gimbal), `state` / `scene` (camera and world), `context` (what handlers
see), `handlers` (what each identifier does, and the handler table per dialect), `entries` /
`streams` / `quirks` (per-model dispatch, subscriptions, quirk switches from the profile), `device`
(sans-I/O core), `faults`, `servers` (asyncio transports) and `simulator` (the object users start).
See docs/simulator.md."""

from __future__ import annotations

from typing import TYPE_CHECKING

from .._lazy import lazy_getattr
from .clock import FakeClock, MonotonicClock
from .faults import FaultInjector, FaultPlan, FaultPlanError
from .quirks import QUIRKS

if TYPE_CHECKING:
    from .background import BackgroundSimulator
    from .device import Device
    from .simulator import Simulator

# The device and its asyncio shell load on first use (PEP 562): the CLI builds `sim`'s options from
# the light modules above without importing the simulator (docs/architecture.md, "A CLI that starts fast").
_LAZY = {"BackgroundSimulator": "background", "Device": "device", "Simulator": "simulator"}


__getattr__ = lazy_getattr(__name__, _LAZY, globals())


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
