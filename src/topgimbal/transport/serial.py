"""Serial: pyserial-asyncio-fast (an optional extra: `pip install topgimbal[serial]`)."""

from __future__ import annotations

import asyncio

from ..errors import TransportError
from .tcp import StreamTransport, _Protocol


class SerialTransport(StreamTransport):
    """`serial:///dev/ttyUSB0?baud=115200` (8N1, as both documents specify)."""

    kind = "serial"

    async def open(self) -> None:
        try:
            import serial_asyncio_fast
        except ImportError:  # pragma: no cover - depends on the installation
            raise TransportError("serial:// needs pyserial-asyncio-fast: pip install 'topgimbal[serial]'") from None
        loop = asyncio.get_running_loop()
        baud = int(self.url.params.get("baud", "115200"))
        try:
            transport, _ = await serial_asyncio_fast.create_serial_connection(
                loop, lambda: _Protocol(self), self.url.path, baudrate=baud
            )
        except Exception as exc:  # pyserial raises SerialException (an OSError) or ValueError
            raise TransportError(f"{self.url}: cannot open: {exc}") from exc
        self._transport = transport
