"""A simulator in its own thread and event loop, for synchronous code (sync tests, CLI tests,
browser tests):

    with BackgroundSimulator("C12", seed=1, listen={"udp": [("127.0.0.1", 0)]}) as bg:
        talk_to(bg.url)
        assert bg.call(lambda sim: sim.camera.recording)
"""

from __future__ import annotations

import asyncio
import threading
from collections.abc import Callable
from typing import Any, TypeVar

from .simulator import Simulator

T = TypeVar("T")


class BackgroundSimulator:
    def __init__(self, model: str = "C12", *, listen: dict[str, Any] | None = None, **kwargs: Any) -> None:
        self.sim = Simulator(model, listen=listen, **kwargs)
        self._loop = asyncio.new_event_loop()
        self._thread = threading.Thread(target=self._run, name=f"topgimbal-sim-{model}", daemon=True)
        self._ready = threading.Event()
        self._error: BaseException | None = None

    def _run(self) -> None:
        asyncio.set_event_loop(self._loop)
        try:
            self._loop.run_until_complete(self.sim.__aenter__())
        except BaseException as exc:  # hand the failure to the starting thread
            self._error = exc
            self._ready.set()
            return
        self._ready.set()
        self._loop.run_forever()
        self._loop.run_until_complete(self.sim.stop())
        self._loop.close()

    def start(self) -> BackgroundSimulator:
        self._thread.start()
        self._ready.wait(10)
        if self._error is not None:
            raise self._error
        return self

    def stop(self) -> None:
        if self._thread.is_alive():
            self._loop.call_soon_threadsafe(self._loop.stop)
            self._thread.join(10)

    def __enter__(self) -> BackgroundSimulator:
        return self.start()

    def __exit__(self, *exc: object) -> None:
        self.stop()

    @property
    def url(self) -> str:
        return self.sim.url

    @property
    def endpoints(self) -> list[tuple[str, str]]:
        return list(self.sim.endpoints)

    def call(self, fn: Callable[[Simulator], T], timeout: float = 10.0) -> T:
        """Run `fn(sim)` on the simulator's loop thread and return its result."""

        async def run() -> T:
            return fn(self.sim)

        return asyncio.run_coroutine_threadsafe(run(), self._loop).result(timeout)
