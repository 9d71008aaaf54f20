"""The client SDK: `connect()` / `AsyncClient` (asyncio core) and `Gimbal` (blocking facade)."""

from __future__ import annotations

from .aio import AsyncClient, CatalogCommand, RateKeepAlive, connect
from .session import LinkStats, Pending, Received, Session
from .signs import resolve_signs
from .state import Attitude, SdCard, Stamped, StateCache
from .sync import Gimbal, LoopThreadError
from .traffic import LogRecord, TrafficLog, read_log

__all__ = [
    "AsyncClient", "Attitude", "CatalogCommand", "Gimbal", "LinkStats", "LogRecord", "LoopThreadError", "Pending",
    "RateKeepAlive", "Received", "SdCard", "Session", "Stamped", "StateCache", "TrafficLog", "connect", "read_log",
    "resolve_signs",
]  # fmt: skip
