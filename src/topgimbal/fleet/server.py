"""`FleetServer`: N cameras on one Zenoh session (what `topgimbal zenoh` runs).

    async with FleetServer([CameraSpec("cam1", "udp://127.0.0.1:5000", "C12")],
                           listen=["tcp/127.0.0.1:7447"]) as server:
        await server.wait_closed()

Each camera is a `ServedCamera` (camera.py) with its own SDK client; they share the session and
the event loop. Cameras that do not answer yet are served all the same: their `link` key says
down, calls fail as the SDK's would, and they come up when the camera does."""

from __future__ import annotations

import asyncio
import contextlib
import logging
from collections.abc import Sequence
from typing import Any

from ..client.zenoh_session import open_session
from .camera import MAX_CALLS, ServedCamera
from .specs import CameraSpec, collect

log = logging.getLogger("topgimbal.fleet")


class FleetServer:
    def __init__(
        self,
        cameras: Sequence[CameraSpec],
        *,
        listen: Sequence[str] = (),
        connect: Sequence[str] = (),
        mode: str = "peer",
        config_file: str | None = None,
        rate_hz: float = 50.0,
        max_calls: int = MAX_CALLS,
        client_options: dict[str, Any] | None = None,
    ) -> None:
        self.specs = collect(cameras)
        self.listen, self.connect, self.mode, self.config_file = list(listen), list(connect), mode, config_file
        self.rate_hz = rate_hz
        self.max_calls = max_calls
        self.client_options = dict(client_options or {})
        self.session: Any = None
        self.cameras: dict[str, ServedCamera] = {}
        self._closed = asyncio.Event()

    async def start(self) -> FleetServer:
        # Opening may wait for a router (client mode): off the loop.
        self.session = await asyncio.to_thread(
            open_session, listen=self.listen, connect=self.connect, mode=self.mode, config_file=self.config_file
        )
        try:
            for spec in self.specs:
                self.cameras[spec.name] = ServedCamera(spec, self.session, rate_hz=self.rate_hz,
                                                       max_calls=self.max_calls, client_options=self.client_options)  # fmt: skip
            # All at once: one after the other, 100 cameras took seconds to start and to close.
            await asyncio.gather(*(cam.start() for cam in self.cameras.values()))
        except BaseException:
            await self.close()
            raise
        log.info("serving %d cameras on Zenoh (%s)", len(self.cameras), ", ".join(self.listen + self.connect))
        return self

    async def close(self) -> None:
        await asyncio.gather(*(cam.close() for cam in self.cameras.values()), return_exceptions=True)
        if self.session is not None:
            with contextlib.suppress(Exception):
                await asyncio.to_thread(self.session.close)
            self.session = None
        self._closed.set()

    async def __aenter__(self) -> FleetServer:
        return await self.start()

    async def __aexit__(self, *exc: object) -> None:
        await self.close()

    async def wait_closed(self) -> None:
        await self._closed.wait()
