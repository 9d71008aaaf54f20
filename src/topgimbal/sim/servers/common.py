"""What the UDP, TCP and serial servers share: their limits, log throttling, bind errors."""

from __future__ import annotations

import errno
import logging
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

from ...errors import TopGimbalError
from ...logthrottle import ThrottledLog

Sink = Callable[[Any, bytes, bool], None]
Forget = Callable[[Any], None]
BAUD = 115200
LOOPBACK = "127.0.0.1"
MAX_DATAGRAM = 2048  # the longest TOP frame is ~270 bytes; several may share one datagram
READ_BATCH = 64  # datagrams read per wake-up: one selector round trip serves a burst
TCP_READ_CHUNK = 2048  # bytes taken from one TCP client per turn (several frames)
TCP_PAUSE_READING_BYTES = 4096  # replies backed up beyond this: stop reading that client's requests

log = logging.getLogger("topgimbal.sim")


class ListenError(TopGimbalError, OSError):
    """A listening socket could not be bound; the message names the address and what to do."""


@dataclass(frozen=True)
class Limits:
    """What one remote end, or all of them, can make a simulator hold (docs/simulator.md)."""

    udp_lease_s: float = 60.0  # forget a UDP peer (and its streams) after this long unheard; 0 = never
    max_udp_peers: int = 64  # per UDP endpoint; the least recently heard is forgotten at the cap
    max_tcp_clients: int = 64  # per TCP endpoint; further connections are closed at once
    tcp_buffer_bytes: int = 64 * 1024  # unsent bytes per TCP client before it is dropped
    tcp_sndbuf_bytes: int = 64 * 1024  # kernel send buffer per TCP client (SO_SNDBUF)

    def __post_init__(self) -> None:
        for name in ("max_udp_peers", "max_tcp_clients", "tcp_buffer_bytes", "tcp_sndbuf_bytes"):
            if getattr(self, name) < 1:
                raise ValueError(f"{name}={getattr(self, name)!r}: expected 1 or more")
        if not self.udp_lease_s >= 0:
            raise ValueError(f"udp_lease_s={self.udp_lease_s!r}: expected seconds >= 0 (0 = no lease)")


class Throttled(ThrottledLog):
    """One log line per key per `interval_s`; the next one says how many were held back (the
    shared `logthrottle.ThrottledLog`, with the simulator's logger and words)."""

    def __init__(self, interval_s: float = 10.0) -> None:
        super().__init__(log, interval_s, suffix=" ({} more like this since the last report)")

    def warning(self, kind: str, fmt: str, *args: object) -> bool:
        """`fmt` is the whole line when no `args` follow (the servers' f-strings may hold a %)."""
        return super().warning(kind, fmt, *args) if args else super().warning(kind, "%s", fmt)


def listen_error(kind: str, host: str, port: int, exc: OSError) -> ListenError:
    """A bind failure as one line a user can act on."""
    if exc.errno == errno.EADDRINUSE:
        hint = f"another program (or simulator) has it; use {host}:0 for any free port"
        what = "address already in use"
    elif exc.errno == errno.EACCES:
        hint = f"ports below 1024 need privileges; use {host}:0 for any free port"
        what = "permission denied"
    else:
        hint, what = "use 127.0.0.1:0 for any free loopback port", exc.strerror or str(exc)
    err = ListenError(f"cannot listen on {kind} {host}:{port}: {what} ({hint})")
    err.errno = exc.errno
    return err


def fmt_addr(addr: tuple[Any, ...]) -> str:
    host, port = addr[:2]
    return f"[{host}]:{port}" if ":" in str(host) else f"{host}:{port}"
