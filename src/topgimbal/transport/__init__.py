"""Byte pipes to a device, chosen by URL. Backends are imported only when used (python-can's
BACKENDS table), so `serial://` costs nothing for users who never open a serial port."""

from __future__ import annotations

import importlib

from ..errors import TransportError
from .base import BytesCallback, LostCallback, Transport, TransportURL, network_address, parse_url

BACKENDS: dict[str, tuple[str, str]] = {
    "udp": ("topgimbal.transport.udp", "UdpTransport"),
    "tcp": ("topgimbal.transport.tcp", "TcpTransport"),
    "serial": ("topgimbal.transport.serial", "SerialTransport"),
    "memory": ("topgimbal.transport.memory", "MemoryTransport"),
}


def transport_class(scheme: str) -> type[Transport]:
    try:
        module, name = BACKENDS[scheme]
    except KeyError:
        raise TransportError(f"no transport for scheme {scheme!r}; known: {', '.join(BACKENDS)}") from None
    cls: type[Transport] = getattr(importlib.import_module(module), name)
    return cls


async def open_transport(url: str | TransportURL, on_bytes: BytesCallback, on_lost: LostCallback) -> Transport:
    """Open the transport for `url` and return it once usable."""
    parsed = url if isinstance(url, TransportURL) else parse_url(url)
    transport = transport_class(parsed.scheme)(parsed, on_bytes, on_lost)
    await transport.open()
    return transport


__all__ = [
    "BACKENDS",
    "BytesCallback",
    "LostCallback",
    "Transport",
    "TransportURL",
    "network_address",
    "open_transport",
    "parse_url",
]
