"""The client SDK: `connect()` / `AsyncClient` (asyncio core) and `Gimbal` (blocking facade).

Layers: engine.py (which frame answers which request; no I/O), link.py (is the device there),
notifier.py (callbacks), streams.py (attitude streams), core.py (the asyncio shell), api_*.py (the
typed methods, written once for both clients), aio.py / sync.py (the two clients)."""

from __future__ import annotations

from .aio import AsyncClient, CatalogCommand, RateKeepAlive, connect
from .camera_api import CameraAPI
from .engine import Engine, Inbound, Transaction
from .link import LinkEvent, LinkMonitor
from .signs import resolve_signs
from .state import Attitude, SdCard, Stamped, StateCache
from .stats import LinkStats
from .streams import AttitudeStream
from .sync import ClientClosedError, Gimbal, LoopThreadError, SyncAttitudeStream
from .traffic import LogRecord, TrafficLog, read_log

__all__ = [
    "AsyncClient", "Attitude", "AttitudeStream", "CameraAPI", "CatalogCommand", "ClientClosedError", "Engine", "Gimbal", "Inbound",
    "LinkEvent", "LinkMonitor", "LinkStats", "LogRecord", "LoopThreadError", "RateKeepAlive", "SdCard", "Stamped",
    "StateCache", "SyncAttitudeStream", "TrafficLog", "Transaction", "connect", "read_log", "resolve_signs",
]  # fmt: skip
