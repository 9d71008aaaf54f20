"""`FleetServer`: N cameras on one Zenoh session (what `topgimbal zenoh` runs).

    async with FleetServer([CameraSpec("cam1", "udp://127.0.0.1:5000", "C12")],
                           listen=["tcp/127.0.0.1:7447"]) as server:
        await server.wait_closed()

Each camera is a `ServedCamera` (camera.py) with its own SDK client; they share the session and
the event loop, and one `AttitudeBatch` (batch.py) that puts all their samples together on
`topgimbal/@attitude/<session id>`. Cameras that do not answer yet are served all the same: their `link` key says
down, calls fail as the SDK's would, and they come up when the camera does.

Before serving, the session's exposure is checked (fleet/access.py: beyond loopback only with
Zenoh access control, or `insecure=True`, logged every INSECURE_LOG_EVERY_S), and every name is
looked up: a name whose liveliness token another server holds is refused (DuplicateCameraError),
so one call never moves two cameras."""

from __future__ import annotations

import asyncio
import contextlib
import logging
from collections.abc import Sequence
from typing import Any

from ..client.remote_keys import ROOT
from ..client.zenoh_session import make_config, open_session
from ..errors import TopGimbalError
from .access import INSECURE_LOG_EVERY_S, check_exposure
from .batch import DEFAULT_BATCH_S, AttitudeBatch
from .camera import GONE_CHECK_S, MAX_CALLS, STATE_POLL_S, ServedCamera
from .specs import CameraSpec, collect
from .ticker import CameraTicker

log = logging.getLogger("topgimbal.fleet")

NAME_CHECK_S = 2.0  # how long the liveliness query for names already served waits for answers


class DuplicateCameraError(TopGimbalError):
    """Another server on the Zenoh network already serves one of the names."""

    kind = "config"


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
        allow_remote: frozenset[str] = frozenset(),
        insecure: bool = False,
        batch_s: float | None = DEFAULT_BATCH_S,
    ) -> None:
        self.specs = collect(cameras)
        self.batch_s = batch_s  # the batch key's wait (fleet/batch.py); None: no batch key
        self.batch: AttitudeBatch | None = None
        self.ticker: CameraTicker | None = None  # every camera's periodic checks (fleet/ticker.py)
        self.allow_remote = allow_remote
        self.insecure = insecure
        self.protection = ""
        self.listen, self.connect, self.mode, self.config_file = list(listen), list(connect), mode, config_file
        self.rate_hz = rate_hz
        self.max_calls = max_calls
        self.client_options = dict(client_options or {})
        self.session: Any = None
        self.cameras: dict[str, ServedCamera] = {}
        self._closed = asyncio.Event()

    async def start(self) -> FleetServer:
        conf = make_config(listen=self.listen, connect=self.connect, mode=self.mode, config_file=self.config_file)
        # AccessConfigError (a ValueError) before any socket is opened
        self.protection = check_exposure([*self.listen, *self.connect], conf, self.insecure, self.mode)
        log.info("zenoh: %s", self.protection)
        # Opening may wait for a router (client mode): off the loop.
        self.session = await asyncio.to_thread(
            open_session, listen=self.listen, connect=self.connect, mode=self.mode, config_file=self.config_file
        )
        try:
            await asyncio.to_thread(self._check_names)
            if self.batch_s is not None:
                self.batch = AttitudeBatch(self.session, str(self.session.zid()), self.batch_s)
            self.ticker = CameraTicker(STATE_POLL_S, GONE_CHECK_S)
            for spec in self.specs:
                self.cameras[spec.name] = ServedCamera(spec, self.session, rate_hz=self.rate_hz,
                                                       max_calls=self.max_calls, client_options=self.client_options,
                                                       allow_remote=self.allow_remote, batch=self.batch,
                                                       ticker=self.ticker)  # fmt: skip
            # All at once: one after the other, 100 cameras took seconds to start and to close.
            await asyncio.gather(*(cam.start() for cam in self.cameras.values()))
        except BaseException:
            await self.close()
            raise
        log.info("serving %d cameras on Zenoh (%s)", len(self.cameras), ", ".join(self.listen + self.connect))
        if self.protection.startswith("INSECURE"):
            self._insecure_task = asyncio.ensure_future(self._repeat_insecure())
        return self

    def _check_names(self) -> None:
        """Refuses names whose liveliness token is held elsewhere (blocking: a Zenoh query)."""
        ours = {s.name for s in self.specs}
        replies = self.session.liveliness().get(f"{ROOT}/*", timeout=NAME_CHECK_S)
        taken = sorted({str(r.ok.key_expr).split("/", 1)[1] for r in replies if r.ok is not None} & ours)
        if taken:
            raise DuplicateCameraError(
                f"{', '.join(taken)}: already served by another topgimbal zenoh on this Zenoh network (its "
                "liveliness token is held); one name, one server"
            )

    async def _repeat_insecure(self) -> None:
        while True:
            log.warning("zenoh: %s", self.protection)
            await asyncio.sleep(INSECURE_LOG_EVERY_S)

    async def close(self) -> None:
        task = getattr(self, "_insecure_task", None)
        if task is not None:
            task.cancel()
        await asyncio.gather(*(cam.close() for cam in self.cameras.values()), return_exceptions=True)
        if self.ticker is not None:
            await self.ticker.close()
        if self.batch is not None:
            self.batch.close()
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
