"""Attitude streams: the device's stream kept at what the consumers need, and consumer objects
that stop it deterministically.

`cam.attitude(rate_hz)` returns an `AttitudeStream`: an async iterator and an async context manager.
`async with cam.attitude(20) as s: async for att in s: ...` (or `await s.aclose()`) stops the
device's stream the moment the consumer is done. The short form `async for att in
cam.attitude(20): ... break` keeps working: the object is released when it is dropped (at once in
CPython) and, as a backstop that does not depend on the garbage collector, when it has not asked
for a sample for `abandon_after_s`; a consumer that comes back later simply starts again.

One reconciler task brings the device to the wanted state (the highest rate any consumer or
`attitude_stream()` asked for, or off), so starts and stops from several consumers never race.

Over UDP a device (and every NAT or firewall between) forgets a peer it has not heard from for a
while (the simulator after 60 s), and a stream to a forgotten peer stops. While a stream runs and
the client would otherwise say nothing, it sends the stream's request again every
`stream_renew_s` at most (default 20 s; harmless on devices that do not need it): each wait is
drawn from the last RENEW_SPREAD of that period, so clients started together (a fleet server's
1,000) do not all ask in the same loop turn, which held a fleet server's loop for tens of
milliseconds every 20 s (docs/fleet.md, "ninth round").

Once the model check says the device is another model (`halt()`), nothing is sent for the stream
on the client's own initiative: no renewal, no request again when the device answers a ping or
comes back, and no ping (`active` is false: no silence is watched for a stream not kept). What a
program asks itself (`attitude_stream()`, a new consumer, a stop) still goes out.
"""

from __future__ import annotations

import asyncio
import contextlib
import logging
import math
import random
import weakref
from collections import deque
from collections.abc import Callable

from ..clock import monotonic
from ..errors import ModelMismatchError, RequestTimeoutError, TopGimbalError
from ..timeouts import within
from . import roles
from .ports import StreamPort
from .state import GimbalAttitude

QUEUE_SIZE = 64  # samples held per consumer; the oldest go first when a consumer falls behind
MAX_TAPS = 64
RENEW_SPREAD = 0.25  # a renewal waits between (1 - this) and 1 times stream_renew_s
_spread = random.Random()  # its own: a program's seeded `random` neither moves it nor is moved by it

log = logging.getLogger("topgimbal.client")


def renew_wait_s(every_s: float, u: float | None = None) -> float:
    """The wait before a stream's next renewal: within the last RENEW_SPREAD of `every_s` (`u` in
    [0, 1), drawn when not given), never longer than `every_s`, so a lease is kept as before."""
    return every_s * (1.0 - RENEW_SPREAD * (_spread.random() if u is None else u))


class StreamControl:
    # Slots: one per client, read per sample (a fleet server's 1,000 should stay in cache).
    __slots__ = ("_any_consumer", "_expected", "_listeners", "_renewer", "_taps", "_task", "consumers", "core",
                 "device_rate", "halted", "manual_rate", "renewals")  # fmt: skip

    def __init__(self, core: StreamPort) -> None:
        self.core = core
        # Weak: a consumer dropped without aclose() must be collectable (its __del__ releases it).
        self.consumers: weakref.WeakSet[AttitudeStream] = weakref.WeakSet()
        # whether `consumers` may hold one: tested per sample instead of the WeakSet's own len(),
        # a Python-level call that was 5 % of a 1,000-camera server (issue 45); cleared once seen empty
        self._any_consumer = False
        self.manual_rate: float | None = None
        self.device_rate: float | None = None  # what the device was last told; None: off or unknown
        self._listeners: list[tuple[float, asyncio.Future[GimbalAttitude]]] = []
        self._taps: list[Callable[[GimbalAttitude], None]] = []
        self._task: asyncio.Task[None] | None = None
        self._renewer: asyncio.Task[None] | None = None
        self._expected = False  # what the core was last told (expect_stream)
        self.renewals = 0  # stream requests sent again to keep a UDP peer's lease
        self.halted = False  # the device is another model: the stream is not kept (module docstring)

    @property
    def active(self) -> bool:
        """Something expects attitude frames (the link monitor watches for silence, and pings)."""
        if self.halted:
            return False
        return self.device_rate is not None or self.manual_rate is not None or len(self.consumers) > 0

    def halt(self, on: bool) -> None:
        """The device is (`on`) or is no longer another model than the client's: stop keeping its
        stream, or keep it again (a verdict corrected by a late model name)."""
        if on == self.halted:
            return
        self.halted = on
        if on:
            for task in (self._renewer, self._task):
                if task is not None and not task.done():
                    task.cancel()  # a stream request not sent yet (paced) is not sent at all
            self._renewer = None
            return
        self.resume()

    def _expect(self) -> None:
        """Tell the core whether stream frames may come (asked for, or on at the device)."""
        on = self.wanted() is not None or self.device_rate is not None
        if on != self._expected:
            self._expected = on
            self.core.expect_stream(on)

    def wanted(self) -> float | None:
        rates = [c.rate_hz for c in self.consumers]
        if self.manual_rate is not None:
            rates.append(self.manual_rate)
        return max(rates) if rates else None

    # -- the device's stream ---------------------------------------------------------------------

    async def set_manual(self, rate_hz: float | None) -> None:
        """`attitude_stream(rate)` / `stop_attitude_stream()`: a stream that stays until stopped."""
        self.manual_rate = rate_hz
        await self.reconcile()

    async def acquire(self, consumer: AttitudeStream) -> None:
        self.consumers.add(consumer)
        self._any_consumer = True
        try:
            await self.reconcile()
        except BaseException:
            self.consumers.discard(consumer)
            self.kick()
            raise

    def release(self, consumer: AttitudeStream) -> None:
        self.consumers.discard(consumer)
        self.kick()  # also when the weak set has already let it go

    def kick(self) -> None:
        """Start bringing the device to the wanted state, unless that is under way."""
        if self._task is None or self._task.done():
            loop = self.core.event_loop
            if loop is None or loop.is_closed() or self.core.closed:
                return
            if self.wanted() == self.device_rate:
                self._expect()
                return
            self._task = loop.create_task(self._reconcile())
            self._task.add_done_callback(_consume_error)

    async def reconcile(self) -> None:
        """Wait until the device does what is wanted; raises what stopped it."""
        while self.wanted() != self.device_rate:
            if self._task is None or self._task.done():
                self._task = asyncio.ensure_future(self._reconcile())
                self._task.add_done_callback(_consume_error)
            task = self._task
            try:
                await asyncio.shield(task)
            except asyncio.CancelledError:
                if not (task.cancelled() and self.halted):
                    raise  # our caller's own cancellation
                raise ModelMismatchError(f"{self.core.url}: the device is not a {self.core.model.name}: its attitude "
                                         "stream was not asked for") from None  # fmt: skip
            if task.exception() is not None:
                raise task.exception()  # type: ignore[misc]

    async def _reconcile(self) -> None:
        core = self.core
        ident = roles.require_role(core.dialect, core.model, "attitude_stream", "attitude stream")
        spec = core.dialect.command(ident)
        while (want := self.wanted()) != self.device_rate:
            self._expect()  # before the request: the first samples may come before its answer
            frame = core.build_from(ident, roles.stream_values(spec, want))
            await core.transact(frame, timeout_s=core.timeout_s, retries=core.retries)
            self.device_rate = want
        self._expect()
        self._keep_renewing()

    def _keep_renewing(self) -> None:
        renew = self.core.options.stream_renew_s
        if self.halted or renew is None or not self.core.datagram or self.device_rate is None:
            return
        if self._renewer is None or self._renewer.done():
            self._renewer = asyncio.ensure_future(self._renew(renew))
            self._renewer.add_done_callback(_consume_error)

    async def _renew(self, every_s: float) -> None:
        """Send the running stream's request again every `every_s` while it runs."""
        core = self.core
        ident = roles.require_role(core.dialect, core.model, "attitude_stream", "attitude stream")
        spec = core.dialect.command(ident)
        while self.device_rate is not None and not core.closed:
            await asyncio.sleep(renew_wait_s(every_s))
            rate = self.device_rate
            if self.halted or rate is None or self.wanted() != rate or core.closed or not core.connected:
                continue
            with contextlib.suppress(TopGimbalError):
                await core.transact(core.build_from(ident, roles.stream_values(spec, rate)), timeout_s=core.timeout_s,
                                    retries=core.retries)  # fmt: skip
                self.renewals += 1

    def resume(self) -> None:
        """The device is there again: it may have forgotten its stream (not asked of a device
        that is another model: `halt`)."""
        if self.wanted() is not None and not self.halted:
            self.device_rate = None
            self.kick()

    async def shutdown(self, *, timeout_s: float) -> None:
        """Closing the client: end consumers, and switch the device's stream off if it is on."""
        for c in list(self.consumers):
            c._end(None)
        self.consumers.clear()
        self.manual_rate = None
        if self._renewer is not None:
            self._renewer.cancel()
        if self.device_rate is None:
            return
        core = self.core
        ident = roles.role_ident(core.dialect, core.model, "attitude_stream")
        if ident is None:
            return
        off = core.build_from(ident, roles.stream_values(core.dialect.command(ident), None))
        with contextlib.suppress(TopGimbalError, asyncio.TimeoutError):
            await within(core.transact(off, timeout_s=timeout_s, retries=0), timeout_s * 2)
            self.device_rate = None
            self._expect()

    # -- samples ---------------------------------------------------------------------------------

    def tap(self, callback: Callable[[GimbalAttitude], None]) -> Callable[[], None]:
        """`callback(att)` (sync) for every attitude sample, whatever stream brings it, without a
        consumer's rate thinning or queue (a server republishing every sample: fleet/camera.py).
        Starts no stream; returns a remove function."""
        if len(self._taps) >= MAX_TAPS:
            raise TopGimbalError(f"{MAX_TAPS} attitude taps already registered; remove old ones")
        self._taps.append(callback)

        def remove() -> None:
            with contextlib.suppress(ValueError):
                self._taps.remove(callback)

        return remove

    def publish(self, att: GimbalAttitude) -> None:
        for cb in self._taps:
            try:
                cb(att)
            except Exception:  # one tap's bug is not the link's
                log.exception("attitude tap %r failed", cb)
        live = list(self.consumers) if self._any_consumer else []
        self._any_consumer = bool(live)
        for c in live:
            if c._abandoned(att.t):
                c._started = False  # it starts again if it ever asks for a sample
                c._queue.clear()
                self.release(c)
            else:
                c._push(att)
        if self._listeners:
            keep = []
            for newer_than, fut in self._listeners:
                if fut.done():
                    continue
                if att.t > newer_than:
                    fut.set_result(att)
                else:
                    keep.append((newer_than, fut))
            self._listeners = keep

    def fail(self, error: Exception) -> None:
        """The link is gone: consumers end with `error`; the device's state is unknown."""
        for c in list(self.consumers):
            c._end(error)
        self.consumers.clear()
        self.device_rate = None
        self._expect()
        for _, fut in self._listeners:
            if not fut.done():
                fut.set_exception(error)
        self._listeners = []

    async def next_sample(self, *, newer_than: float, timeout_s: float) -> GimbalAttitude:
        """The next sample from whatever stream runs (none is started here)."""
        loop = asyncio.get_running_loop()
        fut: asyncio.Future[GimbalAttitude] = loop.create_future()
        self._listeners.append((newer_than, fut))
        try:
            return await within(fut, timeout_s)
        except asyncio.TimeoutError:
            raise RequestTimeoutError(f"no attitude sample arrived within {timeout_s:.2f} s") from None
        finally:
            self._listeners = [(n, f) for n, f in self._listeners if f is not fut]


def _consume_error(task: asyncio.Task[None]) -> None:
    if not task.cancelled():
        task.exception()  # retrieved: a failed background stop is not an unhandled error


class AttitudeStream:
    """Attitude samples as they arrive, at most `rate_hz`. See the module docstring."""

    def __init__(self, control: StreamControl, rate_hz: float, *, abandon_after_s: float | None = None) -> None:
        self.control = control
        self.rate_hz = rate_hz
        self.abandon_after_s = abandon_after_s if abandon_after_s is not None else max(5.0, 50.0 / rate_hz)
        self.dropped = 0  # samples lost because the consumer fell behind
        self._queue: deque[GimbalAttitude | BaseException | None] = deque()
        self._waiter: asyncio.Future[None] | None = None
        self._readers = 0  # tasks waiting in __anext__
        self._min_gap = 0.9 / rate_hz  # 10 % slack: device clocks drift
        self._last_t = -math.inf
        self._last_pull = monotonic()
        self._started = False
        self._closed = False

    # -- consumer side -----------------------------------------------------------------------------

    async def start(self) -> AttitudeStream:
        if self._closed:
            raise TopGimbalError("this attitude stream was closed; call cam.attitude() again")
        if not self._started:
            self._started = True
            self._last_pull = monotonic()
            try:
                await self.control.acquire(self)
            except BaseException:
                self._started = False
                raise
        return self

    async def __aenter__(self) -> AttitudeStream:
        return await self.start()

    async def __aexit__(self, *exc: object) -> None:
        await self.aclose()

    def __aiter__(self) -> AttitudeStream:
        return self

    async def __anext__(self) -> GimbalAttitude:
        if self._closed:
            raise StopAsyncIteration
        if not self._started:
            await self.start()
        while not self._queue:
            # One waiter shared by every task reading this stream (a second one used to replace the
            # first's, which then waited forever); shielded: one reader's cancel is not the others'.
            waiter = self._waiter
            if waiter is None or waiter.done():
                waiter = self._waiter = asyncio.get_running_loop().create_future()
            self._readers += 1
            try:
                await asyncio.shield(waiter)
            finally:
                self._readers -= 1
                if not self._readers:
                    self._waiter = None  # no one waits: the stream may be abandoned
        self._last_pull = monotonic()
        item = self._queue[0]
        if item is None or isinstance(item, BaseException):
            self._closed = True  # the end stays queued: every task reading this stream sees it
            if item is None:
                raise StopAsyncIteration
            raise item
        self._queue.popleft()
        return item

    async def aclose(self) -> None:
        """Stop: the device's stream goes off if no one else needs it (waits for that, briefly)."""
        if self._closed and not self._started:
            return
        was_started, self._started, self._closed = self._started, False, True
        self._queue.append(None)  # a task waiting for a sample ends now, not never
        self._wake()
        if was_started:
            self.control.release(self)
            core = self.control.core
            with contextlib.suppress(TopGimbalError, asyncio.TimeoutError):
                await within(self.control.reconcile(), core.timeout_s * (core.retries + 2))

    def __del__(self) -> None:
        # Dropped without aclose() (a `break` out of `async for`): release now, not at GC's leisure.
        if self._started and not self._closed:
            self._closed = True
            with contextlib.suppress(Exception):
                self.control.release(self)

    # -- producer side -----------------------------------------------------------------------------

    def _abandoned(self, now: float) -> bool:
        return self._waiter is None and now - self._last_pull > self.abandon_after_s

    def _push(self, att: GimbalAttitude) -> None:
        if att.t - self._last_t < self._min_gap:
            return
        self._last_t = att.t
        if len(self._queue) >= QUEUE_SIZE:
            self._queue.popleft()
            self.dropped += 1
        self._queue.append(att)
        self._wake()

    def _end(self, error: BaseException | None) -> None:
        self._queue.append(error)
        self._started = False
        self._wake()

    def _wake(self) -> None:
        w = self._waiter
        if w is not None and not w.done():
            w.set_result(None)


__all__ = ["AttitudeStream", "StreamControl"]
