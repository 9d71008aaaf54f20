"""The web console: an aiohttp server and a plain HTML/CSS/ES-module page (no build step, no CDN)
that show and steer one camera through the client SDK. Needs the `console` extra (aiohttp)."""

from __future__ import annotations

from .auth import is_loopback, needs_token, resolve_token
from .server import DEFAULT_HOST, DEFAULT_PORT, ConsoleServer, create_app

__all__ = ["DEFAULT_HOST", "DEFAULT_PORT", "ConsoleServer", "create_app", "is_loopback", "needs_token", "resolve_token"]
