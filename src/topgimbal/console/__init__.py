"""The web console: an aiohttp server and a plain HTML/CSS/ES-module page (no build step, no CDN)
that show and steer one camera through the client SDK. Needs the `console` extra (aiohttp).
What a console runs is a `ConsoleConfig` (config.py): `ConsoleServer.from_config(config)`."""

from __future__ import annotations

from .auth import is_loopback, needs_token, resolve_token
from .config import (
    CameraSource,
    ConsoleConfig,
    ConsoleConfigError,
    FleetSource,
    LinkOptions,
    ProxySource,
    ServeOptions,
    SimSource,
)
from .server import DEFAULT_HOST, DEFAULT_PORT, ConsoleServer, create_app

__all__ = [
    "DEFAULT_HOST",
    "DEFAULT_PORT",
    "CameraSource",
    "ConsoleConfig",
    "ConsoleConfigError",
    "ConsoleServer",
    "FleetSource",
    "LinkOptions",
    "ProxySource",
    "ServeOptions",
    "SimSource",
    "create_app",
    "is_loopback",
    "needs_token",
    "resolve_token",
]
