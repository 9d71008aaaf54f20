"""What the proxy (proxy.py) works out before it forwards anything: the dialect it decodes with
(the model's, the one named, or the one the documented ports say), the device's address as the
pcap shows it (a serial device gets loopback and its dialect's documented port, so Wireshark picks
the right dialect), the URL clients connect to, and what a watcher process is told."""

from __future__ import annotations

import asyncio
import ipaddress
import socket
from collections.abc import Iterable
from typing import Any

from ..protocol import Dialect, get_dialect, get_model
from ..transport import TransportURL
from .packets import Endpoint
from .ports import dialect_for_ports, documented_ports
from .watcher import ProxyError, Watcher


def choose_dialect(model: str | None, dialect: str | None, urls: Iterable[TransportURL]) -> Dialect | None:
    """The model's dialect, else the one named, else the one a documented port of `urls` says."""
    if model:
        return get_model(model)[0]
    if dialect:
        return get_dialect(dialect)
    hint = None
    for url in urls:
        if url.scheme in ("udp", "tcp") and url.port is not None:
            hint = hint or dialect_for_ports(url.scheme, url.port)
    return get_dialect(hint) if hint else None


async def device_endpoint(to: TransportURL, dialect: Dialect | None) -> Endpoint:
    """The device's address as the pcap shows it."""
    if to.scheme == "serial":
        name = dialect.name if dialect else None
        ports = sorted(p for (t, p), d in documented_ports().items() if d == name and t == "udp" and p != 9004)
        return ("127.0.0.1", ports[0] if ports else 5000)
    host, port = to.host, to.port or 0
    try:
        return (str(ipaddress.ip_address(host)), port)
    except ValueError:
        pass
    try:
        infos = await asyncio.get_running_loop().getaddrinfo(host, port, type=socket.SOCK_DGRAM)
    except OSError as exc:
        raise ProxyError(f"cannot resolve {host!r}: {exc}") from None
    return (str(infos[0][4][0]), port)


def listen_url(listen: TransportURL, address: tuple[str, int] | None) -> str:
    """Where clients connect (the real port when the listen URL said 0)."""
    if listen.scheme == "serial" or address is None:
        return listen.text
    host, port = address
    host = f"[{host}]" if ":" in host else host
    return f"{listen.scheme}://{host}:{port}"


def watcher_config(w: Watcher, model: str | None, dialect: Dialect | None) -> dict[str, Any]:
    """What a watcher process needs to do what `w` would do in the proxy's process."""
    return {
        "model": model,
        "dialect": dialect.name if dialect else None,
        "device": w.device,
        "transport": w.transport,
        "pcap": str(w.pcap_path) if w.pcap_path else None,
        "log_path": str(w.log_path) if w.log_path else None,
        "log_header": w.log_header,
    }
