"""The blocking facade: the same client, driven from one event loop in a thread.

This is asyncua's ThreadLoop pattern: there is no second engine, so the sync API can never drift
from the async one. The typed methods are the very same functions (methods.py makes each a
blocking method here). A blocking call made on the loop thread itself (say, from a subscription
callback) would wait for the loop it is blocking: that raises LoopThreadError instead."""

from __future__ import annotations

import asyncio
import contextlib
import threading
from collections.abc import Callable, Coroutine, Iterator
from types import TracebackType
from typing import TYPE_CHECKING, TypeVar, Unpack

from ..errors import TopGimbalError
from ..protocol import CommandSpec, DeviceModel, Dialect, Message
from .aio import AsyncClient
from .api_camera import CameraMethods
from .api_core import CoreMethods
from .api_motion import MotionMethods
from .core import LinkState
from .identity import Verdict
from .methods import SyncDriver
from .notifier import LinkCallback, MessageCallback, TrafficCallback
from .options import ConnectOptions
from .state import Attitude, StateCache
from .stats import LinkStats
from .streams import AttitudeStream

T = TypeVar("T")


class LoopThreadError(TopGimbalError, RuntimeError):
    """A blocking Gimbal method was called on the client's own event-loop thread."""


class ThreadLoop:
    """An event loop running in a daemon thread."""

    def __init__(self) -> None:
        self.loop = asyncio.new_event_loop()
        self._ready = threading.Event()
        self.thread = threading.Thread(target=self._run, name="topgimbal-loop", daemon=True)
        self.thread.start()
        self._ready.wait()

    def _run(self) -> None:
        asyncio.set_event_loop(self.loop)
        self.loop.call_soon(self._ready.set)
        self.loop.run_forever()

    def run(self, coro: Coroutine[object, object, T], timeout: float | None = None) -> T:
        if threading.current_thread() is self.thread:
            coro.close()
            raise LoopThreadError(
                "a blocking Gimbal method was called from the client's event-loop thread (a callback?); "
                "schedule the work elsewhere, or use the AsyncClient (gimbal.aio) inside callbacks"
            )
        return asyncio.run_coroutine_threadsafe(coro, self.loop).result(timeout)

    def stop(self) -> None:
        if self.loop.is_running():
            self.loop.call_soon_threadsafe(self.loop.stop)
        if threading.current_thread() is not self.thread:
            self.thread.join(5)
        if not self.loop.is_running():
            self.loop.close()


class Gimbal(SyncDriver, CoreMethods, MotionMethods, CameraMethods):
    """`with Gimbal("serial:///dev/ttyUSB0?baud=115200", model="SIP") as cam: cam.point(10, -20)`.

    The same typed methods as AsyncClient, blocking. Callbacks run on the loop thread."""

    def __init__(self, url: str, model: str = "C12", **options: Unpack[ConnectOptions]) -> None:
        self._thread = ThreadLoop()
        try:
            self.aio = AsyncClient(url, model, **options)
            self._thread.run(self.aio.open())
        except BaseException:
            self._thread.stop()
            raise
        self.cmd = SyncCommands(self)

    # -- plumbing --------------------------------------------------------------------------------

    def _core(self) -> AsyncClient:
        return self.aio

    def _run(self, coro: Coroutine[object, object, T]) -> T:
        return self._thread.run(coro)

    def close(self) -> None:
        if self._thread.loop.is_closed():
            return
        try:
            self._run(self.aio.close())
        finally:
            self._thread.stop()

    def __enter__(self) -> Gimbal:
        return self

    def __exit__(self, et: type[BaseException] | None, e: BaseException | None, tb: TracebackType | None) -> None:
        self.close()

    # -- the non-coroutine parts -----------------------------------------------------------------

    @property
    def state(self) -> StateCache:
        return self.aio.state

    @property
    def stats(self) -> LinkStats:
        return self.aio.stats

    @property
    def model(self) -> DeviceModel:
        return self.aio.model

    @property
    def dialect(self) -> Dialect:
        return self.aio.dialect

    @property
    def url(self) -> str:
        return self.aio.url

    @property
    def connected(self) -> bool:
        return self.aio.connected

    @property
    def link_state(self) -> LinkState:
        return self.aio.link_state

    def commands(self) -> list[CommandSpec]:
        return self.aio.commands()

    @property
    def model_check(self) -> Verdict:
        """What the device said it is, against the model given (see AsyncClient.model_check)."""
        return self.aio.model_check

    def on_model_check(self, callback: Callable[[Verdict], object]) -> Callable[[], None]:
        return self._run(_call(self.aio.on_model_check, callback))

    def wait_model_check(self, timeout_s: float = 2.0) -> Verdict:
        return self._run(self.aio.wait_model_check(timeout_s))

    def subscribe(self, callback: MessageCallback, ident: str | None = None) -> Callable[[], None]:
        """As AsyncClient.subscribe; the callback runs on the loop thread (keep it short, and do
        not call blocking Gimbal methods from it)."""
        return self._run(_call(self.aio.subscribe, callback, ident))

    def on_traffic(self, callback: TrafficCallback) -> Callable[[], None]:
        return self._run(_call(self.aio.on_traffic, callback))

    def on_link_change(self, callback: LinkCallback) -> Callable[[], None]:
        return self._run(_call(self.aio.on_link_change, callback))

    def video_url(self, lens: str = "visible", *, host: str | None = None, port: int | None = None) -> str:
        """RTSP URL of a lens's stream (no I/O): see AsyncClient.video_url."""
        return self.aio.video_url(lens, host=host, port=port)

    def attitude(self, rate_hz: float = 50, *, timeout_s: float | None = None) -> SyncAttitudeStream:
        """Blocking iterator over attitude samples (`for att in cam.attitude(20): ...`); use
        `with cam.attitude(20) as s:` to stop the stream when the block ends."""
        return SyncAttitudeStream(self, self.aio.attitude(rate_hz), timeout_s)


class SyncAttitudeStream:
    def __init__(self, gimbal: Gimbal, stream: AttitudeStream, timeout_s: float | None) -> None:
        self._g = gimbal
        self._stream = stream
        self._timeout_s = timeout_s
        self._open = True

    def __iter__(self) -> Iterator[Attitude]:
        return self

    def __next__(self) -> Attitude:
        if not self._open:
            raise StopIteration
        try:
            return self._g._thread.run(_anext(self._stream), self._timeout_s)
        except StopAsyncIteration:
            self._open = False
            raise StopIteration from None

    def __enter__(self) -> SyncAttitudeStream:
        self._g._thread.run(self._stream.start())
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    def close(self) -> None:
        if self._open and not self._g._thread.loop.is_closed():
            self._open = False
            with contextlib.suppress(TopGimbalError, RuntimeError):
                self._g._thread.run(self._stream.aclose())

    def __del__(self) -> None:
        with contextlib.suppress(Exception):
            self.close()


async def _anext(stream: AttitudeStream) -> Attitude:
    return await stream.__anext__()


async def _call(fn: Callable[..., T], *args: object) -> T:
    return fn(*args)


class SyncCommands:
    """`cam.cmd.<name>(**values)` and `.read()`, blocking."""

    def __init__(self, gimbal: Gimbal) -> None:
        self._g = gimbal

    def __getattr__(self, name: str) -> SyncCatalogCommand:
        if name.startswith("_"):
            raise AttributeError(name)
        return SyncCatalogCommand(self._g, getattr(self._g.aio.cmd, name).spec)

    def __dir__(self) -> list[str]:
        return dir(self._g.aio.cmd)


class SyncCatalogCommand:
    def __init__(self, gimbal: Gimbal, spec: CommandSpec) -> None:
        self._g = gimbal
        self.spec = spec
        self.__doc__ = f"{spec.ident} {spec.title} ({spec.section})"

    def __call__(self, **values: object) -> Message:
        aio = self._g.aio
        return self._g._run(aio.send_request(aio.build_from(self.spec.ident, values)))

    def read(self, **values: object) -> Message:
        aio = self._g.aio
        return self._g._run(aio.send_request(aio.build_from(self.spec.ident, values, read=True)))


if TYPE_CHECKING:
    from typing import assert_type

    from .state import SdCard

    def _typed(g: Gimbal) -> None:  # mypy checks that the facade's methods carry real types
        assert_type(g.point(1.0, 2.0), Attitude)
        assert_type(g.sd_card(), SdCard)
        assert_type(g.recording(), bool)
