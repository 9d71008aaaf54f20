"""TCP: a stream; frames may be split or merged anywhere (the client's parser reassembles)."""

from __future__ import annotations

import asyncio

from ..errors import TransportError
from ..timeouts import within
from .base import Transport


class _Protocol(asyncio.Protocol):
    def __init__(self, owner: StreamTransport) -> None:
        self.owner = owner

    def data_received(self, data: bytes) -> None:
        self.owner._on_bytes(data)

    def connection_lost(self, exc: Exception | None) -> None:
        self.owner._lost(exc or TransportError(f"{self.owner.url}: the device closed the connection"))


class StreamTransport(Transport):
    """Shared by TCP and serial: an asyncio stream transport."""

    _transport: asyncio.BaseTransport | None = None

    @property
    def write_buffer_size(self) -> int:
        """Bytes handed to `send()` that the peer has not taken yet (a relay bounds it)."""
        t = self._transport
        return t.get_write_buffer_size() if isinstance(t, asyncio.WriteTransport) else 0

    def send(self, data: bytes) -> None:
        self._check_open()
        assert self._transport is not None
        self._transport.write(data)  # type: ignore[attr-defined]

    async def close(self) -> None:
        self._closed = True
        if self._transport is not None:
            t, self._transport = self._transport, None
            self._lost_reported = True  # a deliberate close is not a loss
            t.close()


class TcpTransport(StreamTransport):
    kind = "tcp"

    async def open(self) -> None:
        loop = asyncio.get_running_loop()
        timeout = float(self.url.params.get("connect_timeout", "5"))
        try:
            transport, _ = await within(
                loop.create_connection(lambda: _Protocol(self), self.url.host, self.url.port or 0), timeout
            )
        except (OSError, asyncio.TimeoutError) as exc:
            raise TransportError(f"{self.url}: cannot connect: {exc or 'timed out'}") from exc
        self._transport = transport
