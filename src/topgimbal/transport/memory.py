"""In-memory byte pipes for tests and embedding: `memory://NAME` (pymodbus's NullModem, python-can's
VirtualBus). No sockets, no threads; delivery goes through the event loop like a network's would.

    port = MemoryPort.listen("cam1")              # the device end
    port.on_bytes = lambda data: port.send(reply_to(data))
    cam = await topgimbal.connect("memory://cam1", model="C12")

`set_manipulator(fn)` rewrites what passes (`fn(bytes) -> list[bytes]`: drop with [], split,
duplicate, corrupt), per direction. `memory://NAME?stream=1` delivers like a byte stream (the
manipulator may split anywhere); the default is one datagram per send, like UDP. Ports are named in
one process-wide table (at most MAX_PORTS) and leave it on `close()`.
"""

from __future__ import annotations

import asyncio
from collections.abc import Callable

from ..errors import TransportError
from .base import BytesCallback, LostCallback, Transport, TransportURL

Manipulator = Callable[[bytes], "list[bytes]"]
MAX_PORTS = 1024
_PORTS: dict[str, MemoryPort] = {}


class MemoryPort:
    """The device end of `memory://NAME`. One client at a time."""

    def __init__(self, name: str) -> None:
        self.name = name
        self.on_bytes: BytesCallback | None = None  # what the client sent
        self.client: MemoryTransport | None = None
        self.received: list[bytes] = []
        self._to_device: Manipulator | None = None
        self._to_client: Manipulator | None = None
        self.closed = False

    @classmethod
    def listen(cls, name: str) -> MemoryPort:
        if name in _PORTS:
            raise TransportError(f"memory://{name} is already in use")
        if len(_PORTS) >= MAX_PORTS:
            raise TransportError(f"{MAX_PORTS} memory ports are open; close some")
        port = _PORTS[name] = cls(name)
        return port

    @property
    def url(self) -> str:
        return f"memory://{self.name}"

    def set_manipulator(self, fn: Manipulator | None, direction: str = "both") -> None:
        """`direction`: "in" (client -> device), "out" (device -> client) or "both"."""
        if direction not in ("in", "out", "both"):
            raise ValueError(f"direction={direction!r}: expected in, out or both")
        if direction in ("in", "both"):
            self._to_device = fn
        if direction in ("out", "both"):
            self._to_client = fn

    def send(self, data: bytes) -> None:
        """Bytes from the device to the connected client (dropped when none is connected)."""
        client = self.client
        if client is None or self.closed:
            return
        for chunk in self._to_client(data) if self._to_client else [data]:
            client._deliver_later(chunk)

    def _from_client(self, data: bytes) -> None:
        for chunk in self._to_device(data) if self._to_device else [data]:
            self.received.append(chunk)
            if self.on_bytes is not None:
                self.on_bytes(chunk)

    def disconnect(self) -> None:
        """Drop the connected client as a closed TCP connection or an unplugged cable would."""
        client, self.client = self.client, None
        if client is not None:
            client._lost(TransportError(f"{self.url}: the device closed the link"))

    def close(self) -> None:
        self.closed = True
        self.disconnect()
        if _PORTS.get(self.name) is self:
            del _PORTS[self.name]


class MemoryTransport(Transport):
    kind = "memory"

    def __init__(self, url: TransportURL, on_bytes: BytesCallback, on_lost: LostCallback) -> None:
        super().__init__(url, on_bytes, on_lost)
        self.is_datagram = url.params.get("stream", "0") not in ("1", "true", "yes")
        self._port: MemoryPort | None = None
        self._loop: asyncio.AbstractEventLoop | None = None

    async def open(self) -> None:
        port = _PORTS.get(self.url.host)
        if port is None or port.closed:
            raise TransportError(f"{self.url}: no such memory port (MemoryPort.listen({self.url.host!r}) first)")
        if port.client is not None:
            raise TransportError(f"{self.url}: another client is connected")
        self._loop = asyncio.get_running_loop()
        self._port = port
        port.client = self

    def send(self, data: bytes) -> None:
        self._check_open()
        port, loop = self._port, self._loop
        assert port is not None and loop is not None
        loop.call_soon(port._from_client, bytes(data))

    def _deliver_later(self, data: bytes) -> None:
        if self._loop is not None and not self._closed:
            self._loop.call_soon(self._deliver, data)

    def _deliver(self, data: bytes) -> None:
        if not self._closed:
            self._on_bytes(data)

    async def close(self) -> None:
        self._closed = True
        port, self._port = self._port, None
        if port is not None and port.client is self:
            port.client = None
