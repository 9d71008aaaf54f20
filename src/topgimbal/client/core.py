"""The asyncio shell of the client: one transport, one parser, one engine, one link monitor.

Bytes in -> parser -> engine (which request does it answer) -> state cache, subscribers, streams.
Engine decisions come out as frames to send and finished requests to resolve; one timer serves the
engine's deadlines (retries, pacing) and the link monitor. Link transitions and reconnection are in
connection.py, the model check in model_check.py, host feeds in feeds.py, the typed methods in
api_*.py."""

from __future__ import annotations

import asyncio
import logging
from collections.abc import Callable, Coroutine, Mapping
from types import TracebackType

from ..clock import MonotonicFn, loop_clock, monotonic, wall_time
from ..errors import FieldValueError, LinkLostError, TopGimbalError, TransportError
from ..protocol import DeviceModel, Dialect, Frame, FrameParser, Message, get_model
from ..protocol.frame import DEVICE_ADDRESSES
from ..transport import Transport, TransportURL, open_transport, parse_url
from . import identity, roles
from .builder import FrameBuilder
from .connection import LinkKeeper
from .engine import Engine
from .feeds import HostFeeds
from .link import LinkEvent, LinkMonitor
from .model_check import ModelChecker
from .notifier import LinkCallback, MessageCallback, Notifier, TrafficCallback
from .options import Behaviour, ClientOptions
from .requesting import Requests
from .signs import MessageSigns, resolve_signs
from .state import StateCache, attitude_of
from .stats import LinkStats
from .streams import StreamControl
from .traffic import TrafficLog

log = logging.getLogger("topgimbal.client")

LinkState = dict[str, "bool | str | float | None"]


class ClientCore(Requests):
    """Everything but the typed methods. Open with `await connect(url, model=...)`; options in
    options.py (None: the model profile's value)."""

    def __init__(
        self,
        url: str,
        model: str | DeviceModel = "C12",
        *,
        timeout_s: float = 1.0,
        retries: int = 2,
        signs: Mapping[str, int] | None = None,
        log_path: str | None = None,
        echo_motion: bool | None = None,
        combined_motion: bool | None = None,
        late_window_s: float | None = None,
        dup_window_s: float = 0.05,
        stop_repeats: int | None = None,
        host_address: str | None = None,
        link_timeout_s: float = 3.0,
        reconnect_s: float | None = 1.0,
        min_command_gap_s: float | None = None,
        check_model: bool = True,
        host_feeds: bool = True,
        stream_renew_s: float | None = 20.0,
    ) -> None:
        if not isinstance(model, (str, DeviceModel)):
            raise FieldValueError("model", model, "a model name such as 'C12' or 'SIP'")
        self.options = opts = ClientOptions(
            timeout_s=timeout_s, retries=retries, signs=signs, log_path=log_path, echo_motion=echo_motion,
            combined_motion=combined_motion, late_window_s=late_window_s, dup_window_s=dup_window_s,
            stop_repeats=stop_repeats, host_address=host_address, link_timeout_s=link_timeout_s,
            reconnect_s=reconnect_s, min_command_gap_s=min_command_gap_s, check_model=check_model,
            host_feeds=host_feeds, stream_renew_s=stream_renew_s,
        )  # fmt: skip  # by name: a reordered field can never shift the values
        self.url = url
        self.transport_url: TransportURL = parse_url(url)
        self.dialect: Dialect
        self.model: DeviceModel
        self.dialect, self.model = get_model(model)
        self.behaviour = Behaviour(self.model, opts)
        self.signs = resolve_signs(self.model, signs)
        self._api_signs = MessageSigns(self.signs)
        self.timeout_s = float(timeout_s)
        self.retries = retries
        # TOPOTEK hosts are `P` on the network and `U` on a UART; SkyDroid is always `U`.
        serial = self.transport_url.scheme == "serial"
        self.host_address = host_address or (self.model.host_address if not serial else "U")
        if self.host_address not in self.dialect.host_addresses:
            raise FieldValueError("host_address", host_address, f"one of {', '.join(self.dialect.host_addresses)}")
        self.late_window_s = float(late_window_s) if late_window_s is not None else max(2.0, 2 * timeout_s)
        self.state = StateCache()
        self.stats = LinkStats()
        self.notifier = Notifier()
        self.streams = StreamControl(self)
        self.identity = ModelChecker(self)
        self.feeds = HostFeeds(self)
        self.keeper = LinkKeeper(self)
        self.identity.listeners.append(self._on_verdict)
        self.link: LinkMonitor | None = None
        self.closed = False
        self.angles_ignored = False  # point() saw nothing move after an angle command: use rates
        self._loop: asyncio.AbstractEventLoop | None = None
        self._now: MonotonicFn = monotonic  # the loop's own time once open (clock.loop_clock)
        self._engine: Engine | None = None
        self._transport: Transport | None = None
        self._parser = FrameParser()
        self._timer: asyncio.TimerHandle | None = None
        self._timer_at: float | None = None
        self._traffic_log: TrafficLog | None = None
        self._untraffic: Callable[[], None] = lambda: None
        self._tasks: set[asyncio.Task[object]] = set()
        self._builder = FrameBuilder(self.dialect, self.model, self.signs, self.host_address)

    # -- life cycle ------------------------------------------------------------------------------

    async def open(self) -> ClientCore:
        """Open the link (once: a second open() would leave the first transport running unseen)."""
        if self.closed:
            raise TransportError(f"{self.url}: the client is closed; open a new one (connect(...))")
        if self._engine is not None:
            raise TransportError(f"{self.url}: the client is open already (or being opened)")
        self._loop = asyncio.get_running_loop()
        self._now = loop_clock(self._loop)
        self._engine = Engine(
            clock=self._now,
            late_window_s=self.late_window_s,
            dup_window_s=self.options.dup_window_s,
            stats=self.stats,
            model=self.model,
            dialect=self.dialect,
            min_gap_s=self.behaviour.min_gap_s,
        )
        timeout = self.options.link_timeout_s
        self.link = LinkMonitor(clock=self._now, timeout_s=timeout, ping_after_s=max(0.5, timeout / 3))
        if self.options.log_path:
            self._traffic_log = TrafficLog(
                self.options.log_path, url=self.url, model=self.model.name, dialect=self.dialect.name
            )
            self._untraffic = self.on_traffic(self._traffic_log.record)
        try:
            self._transport = await open_transport(self.transport_url, self.on_bytes, self.keeper.lost)
        except BaseException:
            self._opened_not()
            raise
        self.stats.connected = True
        if self.options.check_model:
            self.background(self.identity.run())
        else:
            self.identity.finish(identity.Verdict(identity.OFF, self.model.name, message="not checked"))
        if self.feeds.enabled:
            self.background(self.feeds.start())
        return self

    def _on_verdict(self, verdict: identity.Verdict) -> None:
        """The device is another model: what the client sends on its own initiative (the attitude
        stream's requests again and renewals, pings, host feeds) is this model's dialect and
        commands, wrong for that device: it stops, with one line. A program's own requests still
        go (the CLI and the MAVLink bridge refuse them with ModelMismatchError before this)."""
        halt = verdict.status == identity.MISMATCH
        if halt == self.streams.halted and halt == self.feeds.halted:
            return
        self.streams.halt(halt)
        self.feeds.halt(halt)
        if halt and self._engine is not None:  # feed frames queued before the verdict, not sent yet
            self._engine.pacer.drop_unsent(frozenset(self.feeds.feeds()))
        if halt:
            log.info("%s: the device is not a %s: the client stops sending the %s's periodic requests (attitude "
                     "stream requests and renewals, pings, host feeds)", self.url, self.model.name, self.model.name,
                     extra={"model_check": verdict})  # fmt: skip
        else:
            log.info("%s: the model check now says %s: periodic requests again", self.url, verdict.status)
        if self._engine is not None:
            self._drive()  # the link monitor no longer expects (or again expects) the stream

    def _opened_not(self) -> None:
        """The transport did not open: undo the rest, so nothing is held and open() may be retried."""
        if self._traffic_log is not None:
            self._traffic_log.close()
            self._traffic_log = None
            self._untraffic()
        self._engine = None
        self.link = None

    def background(self, coro: Coroutine[object, object, object]) -> None:
        """Run a coroutine of the client's own (model check, feeds setup); errors are logged."""
        task: asyncio.Task[object] = asyncio.ensure_future(coro)
        self._tasks.add(task)
        task.add_done_callback(self._task_done)

    def _task_done(self, task: asyncio.Task[object]) -> None:
        self._tasks.discard(task)
        if not task.cancelled() and task.exception() is not None:
            log.info("%s: background task failed: %s", self.url, task.exception())

    async def close(self) -> None:
        """Stop the streams this client started (best effort), fail pending requests, close."""
        if self.closed:
            return
        self.feeds.stop()
        for task in list(self._tasks):
            task.cancel()
        if self.connected:
            await self.streams.shutdown(timeout_s=min(self.timeout_s, 0.3))
        self.closed = True
        self.keeper.stop()
        self._fail_everything(TransportError(f"{self.url}: the client was closed"))
        if self._transport is not None:
            await self._transport.close()
        self.notifier.close()
        if self._traffic_log is not None:
            self._traffic_log.close()

    async def __aenter__(self) -> ClientCore:
        return self

    async def __aexit__(
        self, et: type[BaseException] | None, e: BaseException | None, tb: TracebackType | None
    ) -> None:
        await self.close()

    def on_link_change(self, callback: LinkCallback) -> Callable[[], None]:
        """`callback(up: bool, reason: str)` on every transition (sync or async); returns an
        unsubscribe function."""
        return self.notifier.on_link_change(callback)

    def fail_pending(self, error: TopGimbalError) -> None:
        if self._engine is not None:
            self._engine.fail_all(error)
            self._resolve()

    def _fail_everything(self, error: TopGimbalError) -> None:
        self.stats.connected = False
        if self._timer is not None:
            self._timer.cancel()
            self._timer = self._timer_at = None
        self.fail_pending(error)
        self.streams.fail(error)

    def on_link_event(self, event: LinkEvent) -> None:
        """Carry out a link transition (the link monitor's, through the keeper): counters, log,
        streams resumed or failed with the requests in flight, callbacks."""
        self.stats.connected = self.connected
        if event.up:
            log.info("%s: link up (%s)", self.url, event.reason)
            self.streams.resume()
        else:
            self.stats.link_losses += 1
            log.warning("%s: link lost: %s", self.url, event.reason,
                        extra={"link_lost": True, "heard": bool(self.stats.frames_in)})  # fmt: skip
            err = LinkLostError(f"{self.url}: link lost: {event.reason}")
            self.fail_pending(err)
            self.streams.fail(err)
        self.notifier.link(event.up, event.reason)

    def expect_stream(self, on: bool) -> None:
        """The attitude stream is asked for (or no longer): on the attitude answer's key, frames
        are samples, not copies of an answer, and they answer reads there (engine.set_stream)."""
        ident = roles.role_ident(self.dialect, self.model, "attitude")
        if self._engine is not None and ident is not None:
            self._engine.set_stream(ident, on)

    def resume_streams(self) -> None:
        self.streams.resume()

    def reopened(self, transport: Transport) -> None:
        """A byte-stream link is back: nothing sent on the old one can be answered on it."""
        self._transport = transport
        self._parser.reset()
        if self._engine is not None:
            self._engine.reset()

    # -- bytes in -------------------------------------------------------------------------------

    def on_bytes(self, data: bytes) -> None:
        self.stats.bytes_in += len(data)
        transport = self._transport
        # A datagram ends its frames; bytes to Messages in one pass (the parser's C fast path).
        final = transport is not None and transport.is_datagram
        engine_work = False
        now = self._now()  # one read for the link, the engine and the state: per datagram, not per step
        for item in self._parser.feed_messages(data, self.dialect.decode, final=final):
            if isinstance(item, Message):
                engine_work = self._on_message(item, now) or engine_work
            elif item.kind != "length_mismatch":
                self.stats.bad_frames += 1
        # A stream sample (or a report) changes nothing the engine decides: no frames to send, no
        # request finished, no deadline earlier (the link's moved later). Skipped, per sample.
        if engine_work:
            self._drive()

    # The per-sample path (every attitude frame, 50,000 a second in a fleet server): locals, no
    # call where a test of an attribute does, objects made only when needed.

    def _on_message(self, message: Message, now: float) -> bool:
        """One decoded frame from the line (read at `now`); True when the engine took it for more
        than a sample."""
        frame = message.frame
        self.stats.frames_in += 1
        notifier = self.notifier
        if notifier.wants_traffic:
            notifier.traffic("in", frame, message)
        if frame.src not in DEVICE_ADDRESSES:
            return False  # our own frames echoed by a loopback or a half-duplex line
        engine, link = self._engine, self.link
        assert engine is not None and link is not None
        identity = self.identity
        if identity.unheard and identity.recheck():  # before the link-up callbacks: the verdict is pending again
            self.background(identity.run())
        event = link.on_frame(now)
        if event is not None:
            self.keeper.event(event)
        if message.fields is None and not message.is_error:
            identity.on_foreign(frame)  # a frame of another dialect says the model is wrong
        # Signs are mapped once, here: the engine matches on the frame, never on field values,
        # so it holds (and a request returns) the message already in the API convention.
        api = self._api_signs(message)
        inbound = engine.on_message(api, now)
        if inbound.dispatch:
            if api.fields is not None and not api.is_error:
                self._update_state(api, now)
            if notifier.wants_messages:
                notifier.message(api)
        return inbound.kind != "unsolicited"

    def _update_state(self, m: Message, now: float) -> None:
        wall = wall_time()
        att = self.state.apply_attitude(m, now, wall)  # an attitude sample, the one frame per datagram
        if att is not None:
            self.state.attitude = att
            self.streams.publish(att)
            return
        keyed = self.state.apply(m, now, wall)
        if not keyed:
            return
        att = attitude_of(keyed, "attitude", m.frame.ident, now, wall)
        if att is not None:
            self.state.attitude = att
            self.streams.publish(att)
            return
        earth = attitude_of(keyed, "earth_attitude", m.frame.ident, now, wall)
        if earth is not None:
            self.state.earth_attitude = earth
        if "model_name" in keyed:
            self.identity.on_model_name(keyed["model_name"])

    # -- bytes out and timers -------------------------------------------------------------------

    def _drive(self) -> None:
        """Carry out what the engine decided: send its frames, resolve its finished requests,
        and keep one timer for the next deadline."""
        engine = self._engine
        if engine is None:
            return
        for frame in engine.take_frames():
            self._send_frame(frame)
        self._resolve()
        link = self.link
        assert link is not None and self._loop is not None
        link.expect(self.busy or self.streams.active)
        deadline = engine.next_deadline()
        ld = link.next_deadline()
        if ld is not None and (deadline is None or ld < deadline):
            deadline = ld
        # One timer; re-armed only for an earlier deadline (one that fires early just re-arms),
        # so a request answered in time costs no timer churn.
        if deadline is None or self.closed or (self._timer_at is not None and self._timer_at <= deadline):
            return
        if self._timer is not None:
            self._timer.cancel()
        self._timer_at = deadline
        self._timer = self._loop.call_at(deadline, self._on_timer)

    def _on_timer(self) -> None:
        self._timer = self._timer_at = None
        assert self._engine is not None and self.link is not None
        self._engine.on_tick()
        self.keeper.event(self.link.check())
        self.keeper.maybe_ping(streaming=self.streams.active)
        self._drive()

    def _send_frame(self, frame: Frame) -> None:
        transport = self._transport
        if transport is None or not transport.connected or self.closed:
            return  # the engine's request fails when the link's loss is reported
        data = frame.to_bytes()
        try:
            transport.send(data)
        except TransportError as exc:
            log.info("%s: send failed: %s", self.url, exc)
            return
        self.stats.frames_out += 1
        self.stats.bytes_out += len(data)
        if self.notifier.wants_traffic:
            self.notifier.traffic("out", frame, self.dialect.decode(frame))

    def _resolve(self) -> None:
        assert self._engine is not None
        for tx in self._engine.take_finished():
            fut = tx.waiter
            if fut is None or fut.done():
                continue
            if tx.error is not None:
                fut.set_exception(tx.error)
            else:
                fut.set_result(tx.reply)

    # -- subscriptions ----------------------------------------------------------------------------

    def subscribe(self, callback: MessageCallback, ident: str | None = None) -> Callable[[], None]:
        """Call `callback(message)` for every frame from the device (or only `ident` frames),
        answers included, fields in API units. Sync or async; returns an unsubscribe function."""
        return self.notifier.subscribe(callback, ident)

    def on_traffic(self, callback: TrafficCallback) -> Callable[[], None]:
        """Call `callback(direction, frame, message)` for every frame in ("in") and out ("out"),
        decoded as on the wire (no sign mapping). Returns a remove function."""
        return self.notifier.on_traffic(callback)
