"""Where a simulator listens: the addresses it is given (`"HOST:PORT"` or pairs; an empty host is
loopback), a host as it goes into a URL (IPv6 in brackets), and the peer a `memory://` port is to the
device (something to send to)."""

from __future__ import annotations

from collections.abc import Iterable
from typing import Any

from ..transport.memory import MemoryPort
from .servers import LOOPBACK

Address = tuple[str, int]


def addresses(items: Iterable[Any] | None) -> list[Address]:
    out = []
    for item in items or ():
        if isinstance(item, str):
            host, _, port = item.rpartition(":")
            out.append((host or LOOPBACK, int(port)))
        else:
            host, port = item
            out.append((str(host), int(port)))
    return out


def url_host(host: str) -> str:
    return f"[{host}]" if ":" in host else host


class MemoryPeer:
    """The client of a `memory://` port, as the device sees a peer: something to send to."""

    def __init__(self, port: MemoryPort) -> None:
        self.port = port

    def send(self, data: bytes) -> None:
        self.port.send(data)

    def __repr__(self) -> str:
        return f"<{self.port.url} client>"
