"""The transport interface: a byte pipe to one device, nothing more.

A transport knows nothing about frames. It hands every chunk it receives to `on_bytes` (for a
datagram transport one call per datagram, so the caller can flush its parser at datagram ends) and
reports the end of the link once through `on_lost`."""

from __future__ import annotations

import abc
from collections.abc import Callable
from dataclasses import dataclass, field
from urllib.parse import parse_qs, urlsplit

from ..errors import AddressError, TopGimbalError, TransportError

BytesCallback = Callable[[bytes], None]
LostCallback = Callable[["Exception | None"], None]


@dataclass(frozen=True)
class TransportURL:
    """A parsed `udp://HOST:PORT`, `tcp://HOST:PORT`, `serial:///dev/ttyUSB0?baud=115200` or
    `memory://NAME` (in-process, see transport/memory.py)."""

    scheme: str
    host: str = ""
    port: int | None = None
    path: str = ""
    params: dict[str, str] = field(default_factory=dict)
    text: str = ""

    def __str__(self) -> str:
        return self.text


def parse_url(url: str) -> TransportURL:
    """Parse a device URL, raising AddressError (a TransportError) with the reason when it is not usable."""
    if not isinstance(url, str) or "://" not in url:
        raise AddressError(
            f"device URL {url!r} must look like udp://HOST:PORT, tcp://HOST:PORT or serial:///dev/ttyUSB0?baud=115200"
        )
    parts = urlsplit(url)
    scheme = parts.scheme.lower()
    params = {k: v[-1] for k, v in parse_qs(parts.query).items()}
    if scheme in ("udp", "tcp"):
        try:
            port = parts.port
        except ValueError as exc:
            raise AddressError(f"{url!r}: {exc}") from None
        if not parts.hostname or port is None:
            raise AddressError(f"{url!r}: a {scheme} URL needs a host and a port ({scheme}://HOST:PORT)")
        return TransportURL(scheme, parts.hostname, port, "", params, url)
    if scheme == "serial":
        # serial:///dev/ttyUSB0 (path) or serial://COM3 (Windows names land in netloc)
        path = parts.path if parts.path else parts.netloc
        if parts.netloc and parts.path:
            path = parts.netloc + parts.path
        if not path:
            raise AddressError(f"{url!r}: a serial URL needs a device path (serial:///dev/ttyUSB0?baud=115200)")
        baud = params.get("baud", "115200")
        if not baud.isdigit():
            raise AddressError(f"{url!r}: baud={baud!r} is not a number")
        return TransportURL(scheme, "", None, path, params, url)
    if scheme == "memory":
        if not parts.netloc:
            raise AddressError(f"{url!r}: a memory URL needs a port name (memory://NAME)")
        return TransportURL(scheme, parts.netloc, None, "", params, url)
    raise AddressError(f"{url!r}: unknown scheme {parts.scheme!r}; use udp://, tcp://, serial:// or memory://")


def network_address(url: str) -> tuple[str, str, int] | None:
    """(scheme, host, port) when `url` is a UDP or TCP address with a port; None for anything else
    (a serial line, no port, not a URL): for code that only labels traffic with an address."""
    try:
        parsed = parse_url(url)
    except TopGimbalError:
        return None
    if parsed.scheme not in ("udp", "tcp") or not parsed.port:
        return None
    return parsed.scheme, parsed.host, parsed.port


class Transport(abc.ABC):
    """One open byte pipe. `send` never blocks on the device; `close` is idempotent."""

    kind: str = ""
    is_datagram: bool = False

    def __init__(self, url: TransportURL, on_bytes: BytesCallback, on_lost: LostCallback) -> None:
        self.url = url
        self._on_bytes = on_bytes
        self._on_lost = on_lost
        self._closed = False
        self._lost_reported = False

    @property
    def connected(self) -> bool:
        return not self._closed

    @abc.abstractmethod
    async def open(self) -> None: ...

    @abc.abstractmethod
    def send(self, data: bytes) -> None:
        """Queue `data` for the device; raises TransportError when the link is closed."""

    @abc.abstractmethod
    async def close(self) -> None: ...

    def _lost(self, exc: Exception | None) -> None:
        # asyncio may report the end of a link twice (error, then connection_lost); tell once.
        self._closed = True
        if not self._lost_reported:
            self._lost_reported = True
            self._on_lost(exc)

    def _check_open(self) -> None:
        if self._closed:
            raise TransportError(f"{self.url}: the link is closed")
