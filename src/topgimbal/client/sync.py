"""The blocking facade: the same client, driven from one event loop in a thread.

This is asyncua's ThreadLoop pattern: there is no second engine, so the sync API can never drift
from the async one. The typed methods are the very same functions (methods.py makes each a
blocking method here). A blocking call made on the loop thread itself (say, from a subscription
callback) would wait for the loop it is blocking: that raises LoopThreadError instead."""

from __future__ import annotations

import asyncio
import concurrent.futures
import contextlib
import threading
import weakref
from collections.abc import Callable, Coroutine, Iterator
from types import TracebackType
from typing import TYPE_CHECKING, TypeVar, Unpack

from ..errors import RequestTimeoutError, TopGimbalError, TransportError
from ..protocol import CommandSpec, DeviceModel, Dialect, Message
from .aio import AsyncClient
from .api_camera import CameraMethods
from .api_core import CoreMethods
from .api_feed import FeedMethods
from .api_motion import MotionMethods
from .core import LinkState
from .identity import Verdict
from .methods import SyncDriver
from .notifier import LinkCallback, MessageCallback, TrafficCallback
from .options import ConnectOptions
from .state import GimbalAttitude, StateCache
from .stats import LinkStats
from .streams import AttitudeStream

T = TypeVar("T")

STOP_JOIN_S = 5.0  # how long stop() waits for the loop thread to wind down
WIND_DOWN_ROUNDS = 4  # rounds of cancelling tasks left on a stopped loop
CLOSE_WAIT_S = 5.0  # how long an unclosed Gimbal's finalizer waits for the client to close


class LoopThreadError(TopGimbalError, RuntimeError):
    """A blocking Gimbal method was called on the client's own event-loop thread."""


class ClientClosedError(TransportError):
    """A blocking Gimbal method was called after (or while) the Gimbal was closed."""


class ThreadLoop:
    """An event loop running in a daemon thread.

    `run()` never waits for a loop that will not run its coroutine: once `stop()` is called, new
    calls fail at once with TransportError, and calls that raced it are failed when the loop ends
    (their tasks cancelled and run out). A caller that stops waiting (a timeout, Ctrl-C) cancels
    its coroutine, so no request or stream read is left running for nobody."""

    def __init__(self) -> None:
        self.loop = asyncio.new_event_loop()
        self.stopped = False
        self._lock = threading.RLock()  # re-entrant: a finalizer may run inside it
        self._waiting: set[concurrent.futures.Future[object]] = set()
        self._ready = threading.Event()
        self.thread = threading.Thread(target=self._run, name="topgimbal-loop", daemon=True)
        self.thread.start()
        self._ready.wait()

    def _run(self) -> None:
        loop = self.loop
        asyncio.set_event_loop(loop)
        loop.call_soon(self._ready.set)
        try:
            loop.run_forever()
        finally:
            self._wind_down()

    def _wind_down(self) -> None:
        """On the loop thread once the loop has stopped: cancel what is left (a call that raced
        `stop()`, a background task), let it run out, fail any caller still waiting, close."""
        loop = self.loop
        with self._lock:
            self.stopped = True
        try:
            for _ in range(WIND_DOWN_ROUNDS):  # cancelled tasks may start others; bounded
                # First the callbacks already queued: calls that raced stop() (they fail with
                # "closed"), and tasks' done-callbacks that hand results to waiting threads.
                loop.run_until_complete(asyncio.sleep(0))
                tasks = [t for t in asyncio.all_tasks(loop) if not t.done()]
                if not tasks:
                    break
                for task in tasks:
                    task.cancel()
                loop.run_until_complete(asyncio.gather(*tasks, return_exceptions=True))
        finally:
            with self._lock:
                left, self._waiting = list(self._waiting), set()
            for fut in left:
                fut.cancel()  # its caller raises ClientClosedError
            loop.close()

    def run(self, coro: Coroutine[object, object, T], timeout: float | None = None) -> T:
        if threading.current_thread() is self.thread:
            coro.close()
            raise LoopThreadError(
                "a blocking Gimbal method was called from the client's event-loop thread (a callback?); "
                "schedule the work elsewhere, or use the AsyncClient (gimbal.aio) inside callbacks"
            )
        with self._lock:
            if self.stopped:
                coro.close()
                raise ClientClosedError("the client is closed (Gimbal.close() was called); open a new Gimbal")
            fut = asyncio.run_coroutine_threadsafe(coro, self.loop)
            self._waiting.add(fut)  # type: ignore[arg-type]
        try:
            return fut.result(timeout)
        except concurrent.futures.CancelledError:
            if self.stopped:
                raise ClientClosedError("the client was closed while this call was waiting") from None
            raise
        except BaseException:
            fut.cancel()  # a timeout or Ctrl-C: the coroutine must not go on for nobody
            raise
        finally:
            with self._lock:
                self._waiting.discard(fut)

    def stop(self) -> None:
        with self._lock:
            self.stopped = True
        if not self.loop.is_closed():
            with contextlib.suppress(RuntimeError):  # closed meanwhile by the loop thread
                self.loop.call_soon_threadsafe(self.loop.stop)
        if threading.current_thread() is not self.thread:
            self.thread.join(STOP_JOIN_S)


class Gimbal(SyncDriver, CoreMethods, MotionMethods, CameraMethods, FeedMethods):
    """`with Gimbal("serial:///dev/ttyUSB0?baud=115200", model="SIP") as cam: cam.point(10, -20)`.

    The same typed methods as AsyncClient, blocking. Callbacks run on the loop thread."""

    if TYPE_CHECKING:  # one overload per catalog command (generated): a wrong field name is a mypy error
        from .catalog_types import SyncRequest

        request: SyncRequest

    def __init__(self, url: str, model: str = "C12", **options: Unpack[ConnectOptions]) -> None:
        self._thread = ThreadLoop()
        try:
            self.aio = AsyncClient(url, model, **options)
            self._thread.run(self.aio.open())
        except BaseException:
            self._thread.stop()
            raise
        self.cmd = SyncCommands(self)
        # A Gimbal dropped without close() closes its client and ends its thread (sockets and
        # the loop's file descriptors with it); also at interpreter exit. Holds no reference to self.
        self._finalizer = weakref.finalize(self, _close_quietly, self._thread, self.aio)

    # -- plumbing --------------------------------------------------------------------------------

    def _core(self) -> AsyncClient:
        return self.aio

    def _run(self, coro: Coroutine[object, object, T]) -> T:
        return self._thread.run(coro)

    def close(self) -> None:
        """Stop the client's streams, fail calls still waiting (ClientClosedError, a
        TransportError), close the link, end the thread. Idempotent; later calls raise
        ClientClosedError."""
        if self._finalizer.detach() is None:
            return  # closed already (or being closed by another thread)
        _close(self._thread, self.aio)

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

    def __iter__(self) -> Iterator[GimbalAttitude]:
        return self

    def __next__(self) -> GimbalAttitude:
        if not self._open:
            raise StopIteration
        try:
            return self._g._thread.run(_anext(self._stream), self._timeout_s)
        except TimeoutError:  # the wait for this sample was cancelled: nothing is left waiting
            raise RequestTimeoutError(f"no attitude sample arrived within {self._timeout_s} s") from None
        except StopAsyncIteration:
            self._open = False
            raise StopIteration from None

    def __enter__(self) -> SyncAttitudeStream:
        self._g._thread.run(self._stream.start())
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    def close(self) -> None:
        if self._open and not self._g._thread.stopped:
            self._open = False
            with contextlib.suppress(TopGimbalError, RuntimeError):
                self._g._thread.run(self._stream.aclose())

    def __del__(self) -> None:
        with contextlib.suppress(Exception):
            self.close()


def _close(thread: ThreadLoop, aio: AsyncClient, wait_s: float | None = None) -> None:
    if threading.current_thread() is thread.thread:  # the garbage collector ran on the loop thread
        thread.loop.create_task(aio.close()).add_done_callback(lambda _: thread.stop())
        return
    try:
        if not thread.stopped:
            with contextlib.suppress(ClientClosedError):
                thread.run(aio.close(), wait_s)
    finally:
        thread.stop()


def _close_quietly(thread: ThreadLoop, aio: AsyncClient) -> None:
    with contextlib.suppress(Exception):
        _close(thread, aio, CLOSE_WAIT_S)


async def _anext(stream: AttitudeStream) -> GimbalAttitude:
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
        assert_type(g.point(1.0, 2.0), GimbalAttitude)
        assert_type(g.sd_card(), SdCard)
        assert_type(g.recording(), bool)
