"""The blocking facade: the same AsyncClient, driven from one event loop in a thread.

This is asyncua's ThreadLoop pattern: there is no second engine, so the sync API can never drift
from the async one. A blocking call made on the loop thread itself (say, from a subscription
callback) would wait for the loop it is blocking: that raises LoopThreadError instead."""

from __future__ import annotations

import asyncio
import threading
from collections.abc import Callable, Coroutine, Iterator, Mapping
from types import TracebackType
from typing import Any, TypeVar

from ..errors import TopGimbalError
from .aio import AsyncClient
from .session import LinkStats
from .state import Attitude, StateCache

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

    def run(self, coro: Coroutine[Any, Any, T], timeout: float | None = None) -> T:
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


# Coroutine methods of AsyncClient forwarded one-to-one (same names, same arguments).
FORWARDED = (
    "request", "send_raw", "attitude_stream", "stop_attitude_stream", "get_attitude", "wait_attitude",
    "set_angles", "rates", "stop", "center", "set_mode", "point", "photo", "start_recording",
    "stop_recording", "toggle_recording", "recording", "sd_card", "zoom", "digital_zoom", "focus", "palette",
    "thermal", "version", "identify", "detect_model", "range", "network", "set_network",
)  # fmt: skip


class Gimbal:
    """`with Gimbal("serial:///dev/ttyUSB0?baud=115200", model="SIP") as cam: cam.point(10, -20)`.

    Same methods as AsyncClient, blocking. Subscription callbacks run on the loop thread."""

    def __init__(
        self,
        url: str,
        model: str = "C12",
        *,
        timeout_s: float = 1.0,
        retries: int = 2,
        signs: Mapping[str, int] | None = None,
        log_path: str | None = None,
        **options: Any,
    ) -> None:
        self._thread = ThreadLoop()
        try:
            self.aio = AsyncClient(
                url, model, timeout_s=timeout_s, retries=retries, signs=signs, log_path=log_path, **options
            )
            self._thread.run(self.aio.open())
        except BaseException:
            self._thread.stop()
            raise

    # -- plumbing ------------------------------------------------------------------------------

    def _run(self, coro: Coroutine[Any, Any, T]) -> T:
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

    # -- non-coroutine parts of the API --------------------------------------------------------

    @property
    def state(self) -> StateCache:
        return self.aio.state

    @property
    def stats(self) -> LinkStats:
        return self.aio.stats

    @property
    def model(self) -> Any:
        return self.aio.model

    @property
    def dialect(self) -> Any:
        return self.aio.dialect

    @property
    def url(self) -> str:
        return self.aio.url

    def subscribe(self, callback: Callable[..., Any], ident: str | None = None) -> Callable[[], None]:
        """As AsyncClient.subscribe; the callback runs on the loop thread (keep it short, and do
        not call blocking Gimbal methods from it)."""
        return self._thread.run(_call(self.aio.subscribe, callback, ident))

    def on_traffic(self, callback: Callable[..., Any]) -> Callable[[], None]:
        return self._thread.run(_call(self.aio.on_traffic, callback))

    def attitude(self, rate_hz: float = 50, *, timeout_s: float | None = None) -> Iterator[Attitude]:
        """Blocking iterator over attitude samples (`for att in cam.attitude(20): ...`)."""
        agen = self.aio.attitude(rate_hz)
        try:
            while True:
                try:
                    yield self._thread.run(_anext(agen), timeout_s)
                except StopAsyncIteration:
                    return
        finally:
            if not self._thread.loop.is_closed():
                self._thread.run(agen.aclose())

    def video_url(self, lens: str = "visible", **kw: Any) -> str:
        return self.aio.video_url(lens, **kw)  # plain method: no loop needed (docs/video.md)

    def __getattr__(self, name: str) -> Any:
        # Forward the coroutine methods (listed in FORWARDED) as blocking calls.
        if name in FORWARDED:
            method = getattr(self.aio, name)

            def blocking(*args: Any, **kwargs: Any) -> Any:
                return self._run(method(*args, **kwargs))

            blocking.__name__ = name
            blocking.__doc__ = method.__doc__
            return blocking
        if name == "cmd":
            return _SyncCommands(self)
        raise AttributeError(f"{type(self).__name__!s} has no attribute {name!r}")

    def __dir__(self) -> list[str]:
        return sorted({*super().__dir__(), *FORWARDED, "cmd"})


async def _anext(agen: Any) -> Any:
    return await agen.__anext__()


async def _call(fn: Callable[..., T], *args: Any) -> T:
    return fn(*args)


class _SyncCommands:
    def __init__(self, gimbal: Gimbal) -> None:
        self._g = gimbal

    def __getattr__(self, name: str) -> Any:
        cmd = getattr(self._g.aio.cmd, name)

        class _Blocking:
            spec = cmd.spec

            def __call__(_self, **values: Any) -> Any:  # noqa: N805
                return self._g._run(cmd(**values))

            def read(_self, **values: Any) -> Any:  # noqa: N805
                return self._g._run(cmd.read(**values))

        return _Blocking()
