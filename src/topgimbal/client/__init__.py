"""The client SDK: `connect()` / `AsyncClient` (asyncio core) and `Gimbal` (blocking facade).

Layers: engine.py (which frame answers which request; no I/O), link.py (is the device there),
notifier.py (callbacks), streams.py (attitude streams), core.py (the asyncio shell), api_*.py (the
typed methods, written once for both clients), aio.py / sync.py (the two clients)."""

from __future__ import annotations

from typing import TYPE_CHECKING

from .._lazy import lazy_getattr

if TYPE_CHECKING:
    from .aio import AsyncClient, CatalogCommand, RateKeepAlive, connect
    from .camera_api import CameraAPI
    from .engine import Engine, Inbound, Transaction
    from .link import LinkEvent, LinkMonitor
    from .signs import resolve_signs
    from .state import Attitude, GimbalAttitude, SdCard, Stamped, StateCache
    from .stats import LinkStats
    from .streams import AttitudeStream
    from .sync import ClientClosedError, Gimbal, LoopThreadError, SyncAttitudeStream
    from .traffic import LogRecord, TrafficLog, read_log

# Every name loads on first use (PEP 562): `from topgimbal.client.roles import ...` or the CLI's
# `--help` does not import asyncio, the engine and both clients.
_LAZY = {
    "AsyncClient": "aio",
    "CatalogCommand": "aio",
    "RateKeepAlive": "aio",
    "connect": "aio",
    "CameraAPI": "camera_api",
    "Engine": "engine",
    "Inbound": "engine",
    "Transaction": "engine",
    "LinkEvent": "link",
    "LinkMonitor": "link",
    "resolve_signs": "signs",
    "Attitude": "state",
    "GimbalAttitude": "state",
    "SdCard": "state",
    "Stamped": "state",
    "StateCache": "state",
    "LinkStats": "stats",
    "AttitudeStream": "streams",
    "ClientClosedError": "sync",
    "Gimbal": "sync",
    "LoopThreadError": "sync",
    "SyncAttitudeStream": "sync",
    "LogRecord": "traffic",
    "TrafficLog": "traffic",
    "read_log": "traffic",
}


__getattr__ = lazy_getattr(__name__, _LAZY, globals())


__all__ = [
    "AsyncClient", "Attitude", "AttitudeStream", "CameraAPI", "CatalogCommand", "ClientClosedError", "Engine", "Gimbal", "GimbalAttitude", "Inbound",
    "LinkEvent", "LinkMonitor", "LinkStats", "LogRecord", "LoopThreadError", "RateKeepAlive", "SdCard", "Stamped",
    "StateCache", "SyncAttitudeStream", "TrafficLog", "Transaction", "connect", "read_log", "resolve_signs",
]  # fmt: skip
