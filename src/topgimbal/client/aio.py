"""The asyncio client: `connect()` / `AsyncClient`.

`AsyncClient` is the core (core.py: transport, parser, engine, link monitor, streams) plus the
typed methods (api_core.py, api_motion.py, api_camera.py), the catalog-driven `cmd.<name>` and
the joystick helper `rate_control()`."""

from __future__ import annotations

import asyncio
import contextlib
from collections.abc import Callable, Generator
from types import TracebackType
from typing import TYPE_CHECKING, Unpack

from ..errors import FieldValueError
from ..protocol import CommandSpec, DeviceModel, Message
from ..timeouts import within
from . import checks, identity, roles
from .api_camera import CameraMethods
from .api_core import CoreMethods, _rate
from .api_feed import FeedMethods
from .api_motion import MotionMethods
from .core import ClientCore
from .options import ConnectOptions
from .streams import AttitudeStream

if TYPE_CHECKING:
    from .catalog_types import AsyncRequest


class AsyncClient(ClientCore, CoreMethods, MotionMethods, CameraMethods, FeedMethods):
    """A connection to one gimbal camera. Open with `await connect(url, model=...)`."""

    if TYPE_CHECKING:  # one overload per catalog command (generated): a wrong field name is a mypy error
        request: AsyncRequest

    def __init__(self, url: str, model: str | DeviceModel = "C12", **options: Unpack[ConnectOptions]) -> None:
        super().__init__(url, model, **options)
        self.cmd = CommandNamespace(self)

    async def open(self) -> AsyncClient:
        await super().open()
        return self

    async def __aenter__(self) -> AsyncClient:
        return self

    @property
    def model_check(self) -> identity.Verdict:
        """What the device said it is, against the model the client was told (`status`: pending,
        ok, mismatch, unknown, off; `message`, `fits`)."""
        return self.identity.verdict

    def on_model_check(self, callback: Callable[[identity.Verdict], object]) -> Callable[[], None]:
        """`callback(verdict)` whenever the model check's verdict changes; returns a remove function."""
        self.identity.listeners.append(callback)
        return lambda: self.identity.listeners.remove(callback) if callback in self.identity.listeners else None

    async def wait_model_check(self, timeout_s: float = 2.0) -> identity.Verdict:
        """The model check's verdict once it has one (or whatever it is after `timeout_s`)."""
        try:
            await within(self.identity.done.wait(), timeout_s)
        except asyncio.TimeoutError:
            pass
        return self.identity.verdict

    def attitude(self, rate_hz: float = 50, *, abandon_after_s: float | None = None) -> AttitudeStream:
        """Attitude samples as they arrive, at most `rate_hz`: `async for att in
        cam.attitude(20)`, or `async with cam.attitude(20) as stream:` to stop the device's stream
        the moment the block ends. Starts the stream when needed and stops it when no consumer
        is left; ends with LinkLostError when the device goes quiet (see streams.py)."""
        checks.positive_seconds("abandon_after_s", abandon_after_s)
        return AttitudeStream(self.streams, _rate(rate_hz), abandon_after_s=abandon_after_s)

    def video_url(self, lens: str = "visible", *, host: str | None = None, port: int | None = None) -> str:
        """RTSP URL of a lens's stream (the model's documented port and path) at the camera's
        address: the control URL's host unless `host` says otherwise. See docs/video.md."""
        from ..protocol.streams import host_of, video_url  # the per-model stream table (pure)

        return video_url(self.model.name, host or host_of(self.url), lens, port=port)

    def rate_control(self, interval_s: float = 0.1) -> RateKeepAlive:
        """A joystick helper: `async with cam.rate_control() as joy: joy.set(yaw_deg_s=10)`
        re-sends the current rates every `interval_s` (fire-and-forget) and stops on exit."""
        checks.positive_seconds("interval_s", interval_s, allow_none=False)
        return RateKeepAlive(self, interval_s)


class CommandNamespace:
    """`cam.cmd.<name>(**values)` for every catalog command of the model (by catalog name or
    identifier), `cam.cmd.<name>.read()` for queries; driven by the catalog, not hand-written."""

    def __init__(self, client: AsyncClient) -> None:
        self._client = client

    def __getattr__(self, name: str) -> CatalogCommand:
        if name.startswith("_"):
            raise AttributeError(name)
        try:
            spec = self._client.dialect.command(name)
        except Exception:
            raise AttributeError(f"no command {name!r} in the {self._client.dialect.name} catalog") from None
        return CatalogCommand(self._client, spec)

    def __dir__(self) -> list[str]:
        return sorted(c.name for c in self._client.commands())


class CatalogCommand:
    def __init__(self, client: AsyncClient, spec: CommandSpec) -> None:
        self.client = client
        self.spec = spec
        self.__doc__ = f"{spec.ident} {spec.title} ({spec.section})"

    async def __call__(self, **values: object) -> Message:
        return await self.client.send_request(self.client.build_from(self.spec.ident, values))

    async def read(self, **values: object) -> Message:
        return await self.client.send_request(self.client.build_from(self.spec.ident, values, read=True))


class RateKeepAlive:
    """Re-sends the last rates every `interval_s` so devices that stop a rate command after a
    silence keep turning, and stops the gimbal on exit."""

    def __init__(self, client: AsyncClient, interval_s: float) -> None:
        self.client = client
        self.interval_s = interval_s
        self.rates: tuple[float, float, float] = (0.0, 0.0, 0.0)
        self._task: asyncio.Task[None] | None = None
        self.sent = 0

    def set(self, yaw_deg_s: float = 0, pitch_deg_s: float = 0, roll_deg_s: float = 0) -> None:
        for name, v in (("yaw_deg_s", yaw_deg_s), ("pitch_deg_s", pitch_deg_s), ("roll_deg_s", roll_deg_s)):
            if not checks.is_number(v):
                raise FieldValueError(name, v, "a rate in deg/s")
        wanted = {"yaw": yaw_deg_s, "pitch": pitch_deg_s, **({"roll": roll_deg_s} if roll_deg_s else {})}
        c = self.client
        for cmd in roles.motion_plan(c.dialect, c.model, "rate", wanted, combined=c.behaviour.combined):
            c.build_from(cmd.spec.ident, cmd.values)  # validate now
        self.rates = (yaw_deg_s, pitch_deg_s, roll_deg_s)

    async def _run(self) -> None:
        while True:
            y, p, r = self.rates
            with contextlib.suppress(Exception):
                await self.client.rates(y, p, r, wait_reply=False)
                self.sent += 1
            await asyncio.sleep(self.interval_s)

    async def __aenter__(self) -> RateKeepAlive:
        self._task = asyncio.ensure_future(self._run())
        return self

    async def __aexit__(self, *exc: object) -> None:
        if self._task is not None:
            self._task.cancel()
            with contextlib.suppress(asyncio.CancelledError):
                await self._task
        await self.client.stop()


class _Connector:
    """What `connect()` returns: awaitable (an open client) and an async context manager."""

    def __init__(self, client: AsyncClient) -> None:
        self._client = client

    def __await__(self) -> Generator[object, None, AsyncClient]:
        return self._client.open().__await__()

    async def __aenter__(self) -> AsyncClient:
        return await self._client.open()

    async def __aexit__(
        self, et: type[BaseException] | None, e: BaseException | None, tb: TracebackType | None
    ) -> None:
        await self._client.close()


def connect(url: str, model: str | DeviceModel = "C12", **options: Unpack[ConnectOptions]) -> _Connector:
    """Open a client: `cam = await connect(url, model="C12")` or
    `async with connect(url, model="SIP") as cam: ...`. Options (see docs/client.md and
    client/options.py; None takes the model profile's value): echo_motion, combined_motion,
    late_window_s, dup_window_s, stop_repeats, host_address, link_timeout_s, reconnect_s,
    min_command_gap_s, check_model, host_feeds, stream_renew_s; and timeout_s (per attempt, 1 s),
    retries (2), signs (per-axis overrides), log_path (JSONL traffic log).
    `zenoh/NAME?connect=tcp/HOST:PORT`: a camera served by `topgimbal zenoh` (client/remote.py)."""
    if isinstance(url, str) and url.startswith("zenoh"):  # a remote camera: same methods, over Zenoh
        from .remote import RemoteClient

        return _Connector(RemoteClient(url, model, **options))  # type: ignore[arg-type]
    return _Connector(AsyncClient(url, model, **options))


if TYPE_CHECKING:
    from .camera_api import CameraAPI

    def _conforms(client: AsyncClient) -> CameraAPI:
        return client  # mypy checks that AsyncClient provides the CameraAPI protocol
