"""The asyncio shell of the client: one transport, one parser, one engine, one link monitor.

Bytes in -> parser -> engine (which request does it answer) -> state cache, subscribers, streams.
Engine decisions come out as frames to send and finished requests to resolve; one timer serves the
engine's deadlines, the link monitor and reconnection. The typed methods live in api_*.py."""

from __future__ import annotations

import asyncio
import contextlib
import logging
import time
from collections.abc import Callable, Mapping
from types import TracebackType
from typing import Any

from ..errors import (
    FieldValueError,
    LinkLostError,
    TopGimbalError,
    TransportError,
)
from ..protocol import CommandSpec, DeviceModel, Dialect, Frame, FrameParser, Message, get_model
from ..protocol.frame import DEVICE_ADDRESSES
from ..transport import Transport, TransportURL, open_transport, parse_url
from . import checks, roles
from .builder import FrameBuilder
from .engine import Engine, Transaction
from .link import LinkEvent, LinkMonitor
from .notifier import LinkCallback, MessageCallback, Notifier, TrafficCallback
from .signs import map_message, resolve_signs
from .state import Attitude, StateCache
from .stats import LinkStats
from .streams import StreamControl
from .traffic import TrafficLog

log = logging.getLogger("topgimbal.client")


class ClientCore:
    """Everything but the typed methods. Open with `await connect(url, model=...)`."""

    def __init__(
        self,
        url: str,
        model: str = "C12",
        *,
        timeout_s: float = 1.0,
        retries: int = 2,
        signs: Mapping[str, int] | None = None,
        log_path: str | None = None,
        echo_motion: bool = True,
        combined_motion: bool = True,
        late_window_s: float | None = None,
        dup_window_s: float = 0.05,
        stop_repeats: int = 3,
        host_address: str | None = None,
        link_timeout_s: float = 3.0,
        reconnect_s: float | None = 1.0,
    ) -> None:
        if not isinstance(model, str):
            raise FieldValueError("model", model, "a model name such as 'C12' or 'SIP'")
        checks.positive_seconds("timeout_s", timeout_s, allow_none=False)
        checks.count("retries", retries, allow_none=False)
        checks.positive_seconds("late_window_s", late_window_s)
        checks.positive_seconds("dup_window_s", dup_window_s, allow_none=False, allow_zero=True)
        checks.positive_seconds("link_timeout_s", link_timeout_s, allow_none=False)
        checks.positive_seconds("reconnect_s", reconnect_s)
        checks.count("stop_repeats", stop_repeats, allow_none=False, maximum=20)
        for name, flag in (("echo_motion", echo_motion), ("combined_motion", combined_motion)):
            if not isinstance(flag, bool):
                raise FieldValueError(name, flag, "True or False")
        self.url = url
        self._url: TransportURL = parse_url(url)
        self.dialect: Dialect
        self.model: DeviceModel
        self.dialect, self.model = get_model(model)
        self.signs = resolve_signs(self.model, signs)
        self.timeout_s = float(timeout_s)
        self.retries = retries
        self.echo_motion = echo_motion
        self.combined_motion = combined_motion
        self.stop_repeats = stop_repeats
        self.link_timeout_s = float(link_timeout_s)
        self.reconnect_s = reconnect_s
        # TOPOTEK hosts are `P` on the network and `U` on a UART; SkyDroid is always `U`.
        serial = self._url.scheme == "serial"
        self.host_address = host_address or (self.model.host_address if not serial else "U")
        if self.host_address not in self.dialect.host_addresses:
            raise FieldValueError("host_address", host_address, f"one of {', '.join(self.dialect.host_addresses)}")
        self.late_window_s = float(late_window_s) if late_window_s is not None else max(2.0, 2 * timeout_s)
        self.state = StateCache()
        self.stats = LinkStats()
        self._log_path = log_path
        self._loop: asyncio.AbstractEventLoop | None = None
        self._engine: Engine | None = None
        self._link: LinkMonitor | None = None
        self._transport: Transport | None = None
        self._parser = FrameParser()
        self._notifier = Notifier()
        self.streams = StreamControl(self)
        self._timer: asyncio.TimerHandle | None = None
        self._timer_at: float | None = None
        self._traffic_log: TrafficLog | None = None
        self._reconnect_task: asyncio.Task[None] | None = None
        self._ping_task: asyncio.Task[None] | None = None
        self._dup_window_s = float(dup_window_s)
        self._builder = FrameBuilder(self.dialect, self.model, self.signs, self.host_address)
        self._closed = False

    # -- life cycle ------------------------------------------------------------------------------

    async def open(self) -> ClientCore:
        self._loop = loop = asyncio.get_running_loop()
        self._engine = Engine(
            clock=loop.time, late_window_s=self.late_window_s, dup_window_s=self._dup_window_s, stats=self.stats
        )
        self._link = LinkMonitor(
            clock=loop.time, timeout_s=self.link_timeout_s, ping_after_s=max(0.5, self.link_timeout_s / 3)
        )
        if self._log_path:
            self._traffic_log = TrafficLog(
                self._log_path, url=self.url, model=self.model.name, dialect=self.dialect.name
            )
            self.on_traffic(self._traffic_log.record)
        self._transport = await open_transport(self._url, self._on_bytes, self._on_lost)
        self.stats.connected = True
        return self

    async def close(self) -> None:
        """Stop the streams this client started (best effort), fail pending requests, close."""
        if self._closed:
            return
        if self.connected:
            await self.streams.shutdown(timeout_s=min(self.timeout_s, 0.3))
        self._closed = True
        for task in (self._reconnect_task, self._ping_task):
            if task is not None:
                task.cancel()
        self._fail_everything(TransportError(f"{self.url}: the client was closed"))
        if self._transport is not None:
            await self._transport.close()
        self._notifier.close()
        if self._traffic_log is not None:
            self._traffic_log.close()

    async def __aenter__(self) -> ClientCore:
        return self

    async def __aexit__(
        self, et: type[BaseException] | None, e: BaseException | None, tb: TracebackType | None
    ) -> None:
        await self.close()

    @property
    def connected(self) -> bool:
        """True while the transport is open and the device has not gone quiet."""
        return (
            not self._closed
            and self._transport is not None
            and self._transport.connected
            and (self._link is None or self._link.up)
        )

    @property
    def link_up(self) -> bool:
        return self.connected

    @property
    def link_state(self) -> dict[str, Any]:
        """`{"up", "reason", "silent_s"}`: why the link is down, how long nothing has come."""
        link = self._link
        silent = None if link is None or link.last_in is None else round(link.silent_for(), 3)
        reason = "" if self.connected else (link.reason if link is not None and link.reason else "closed")
        return {"up": self.connected, "reason": reason, "silent_s": silent}

    def on_link_change(self, callback: LinkCallback) -> Callable[[], None]:
        """`callback(up: bool, reason: str)` on every transition (sync or async); returns an
        unsubscribe function."""
        return self._notifier.on_link_change(callback)

    def _fail_everything(self, error: TopGimbalError) -> None:
        self.stats.connected = False
        if self._timer is not None:
            self._timer.cancel()
            self._timer = self._timer_at = None
        if self._engine is not None:
            self._engine.fail_all(error)
            self._resolve()
        self.streams.fail(error)

    def _link_event(self, event: LinkEvent | None) -> None:
        if event is None:
            return
        self.stats.connected = self.connected
        if event.up:
            log.info("%s: link up (%s)", self.url, event.reason)
            self.streams.resume()
        else:
            self.stats.link_losses += 1
            log.warning("%s: link lost: %s", self.url, event.reason)
            err = LinkLostError(f"{self.url}: link lost: {event.reason}")
            if self._engine is not None:
                self._engine.fail_all(err)
                self._resolve()
            self.streams.fail(err)
        self._notifier.link(event.up, event.reason)

    def _on_lost(self, exc: Exception | None) -> None:
        if self._closed:
            return
        reason = str(exc) if exc else "the link closed"
        assert self._link is not None
        self._link_event(self._link.on_closed(reason))
        if self.reconnect_s is not None and self._reconnect_task is None:
            self._reconnect_task = asyncio.ensure_future(self._reconnect())

    async def _reconnect(self) -> None:
        """TCP and serial: reopen after a loss, backing off to 5 s between tries."""
        delay = self.reconnect_s or 1.0
        try:
            while not self._closed:
                await asyncio.sleep(delay)
                try:
                    transport = await open_transport(self._url, self._on_bytes, self._on_lost)
                except TransportError as exc:
                    log.info("%s: reconnect failed: %s", self.url, exc)
                    delay = min(5.0, delay * 2)
                    continue
                self._transport = transport
                self._parser.reset()
                if self._engine is not None:
                    self._engine.reset()
                assert self._link is not None
                self._link_event(self._link.on_opened())
                return
        finally:
            self._reconnect_task = None

    # -- bytes in -------------------------------------------------------------------------------

    def _on_bytes(self, data: bytes) -> None:
        self.stats.bytes_in += len(data)
        parser = self._parser
        items = parser.feed(data)
        transport = self._transport
        if transport is not None and transport.is_datagram:
            items += parser.flush()  # a datagram ends its frames
        for item in items:
            if isinstance(item, Frame):
                self._on_frame(item)
            elif item.kind != "length_mismatch":
                self.stats.bad_frames += 1
        self._drive()

    def _on_frame(self, frame: Frame) -> None:
        self.stats.frames_in += 1
        message = self.dialect.decode(frame)
        if self._notifier.wants_traffic:
            self._notifier.traffic("in", frame, message)
        if frame.src not in DEVICE_ADDRESSES:
            return  # our own frames echoed by a loopback or a half-duplex line
        assert self._engine is not None and self._link is not None
        self._link_event(self._link.on_frame())
        # Signs are mapped once, here: the engine matches on the frame, never on field values,
        # so it holds (and a request returns) the message already in the API convention.
        api = map_message(message, self.signs) if message.spec is not None and message.spec.signed_fields else message
        inbound = self._engine.on_message(api)
        if not inbound.dispatch:
            return
        if api.fields is not None and not api.is_error:
            self._update_state(api)
        self._notifier.message(api)

    def _update_state(self, m: Message) -> None:
        if m.frame.ident in roles.ATTITUDE_IDENTS and "yaw_deg" in m.fields:  # type: ignore[operator]
            f = m.fields
            assert f is not None
            att = Attitude(f["yaw_deg"], f["pitch_deg"], f["roll_deg"], time.monotonic(), time.time(), m.frame.ident)
            self.state.attitude = att
            self.streams.publish(att)
            return
        for key, value in roles.state_updates(m):
            self.state.set(key, value)

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
        link = self._link
        assert link is not None and self._loop is not None
        link.expect(bool(engine.live) or self.streams.active)
        deadline = engine.next_deadline()
        ld = link.next_deadline()
        if ld is not None and (deadline is None or ld < deadline):
            deadline = ld
        # One timer; re-armed only for an earlier deadline (one that fires early just re-arms),
        # so a request answered in time costs no timer churn.
        if deadline is None or self._closed or (self._timer_at is not None and self._timer_at <= deadline):
            return
        if self._timer is not None:
            self._timer.cancel()
        self._timer_at = deadline
        self._timer = self._loop.call_at(deadline, self._on_timer)

    def _on_timer(self) -> None:
        self._timer = self._timer_at = None
        assert self._engine is not None and self._link is not None
        self._engine.on_tick()
        self._link_event(self._link.check())
        # Requests in flight are probes already; a ping is for streams that went quiet.
        if (
            self._link.ping_due()
            and self.streams.active
            and not self._engine.live
            and self._ping_task is None
            and self.connected_transport
        ):
            self._link.pinged()
            self._ping_task = asyncio.ensure_future(self._ping())
        self._drive()

    @property
    def connected_transport(self) -> bool:
        return not self._closed and self._transport is not None and self._transport.connected

    async def _ping(self) -> None:
        """Ask something harmless: an answer tells a quiet stream from a dead device."""
        try:
            ident = roles.ping_ident(self.dialect, self.model)
            if ident is not None:
                with contextlib.suppress(TopGimbalError):
                    await self._request(self.build(ident, read=True), timeout_s=self.timeout_s, retries=0)
                    self.streams.resume()  # the device answers: make sure its stream is on
        finally:
            self._ping_task = None

    def _send_frame(self, frame: Frame) -> None:
        transport = self._transport
        if transport is None or not transport.connected or self._closed:
            return  # the engine's request fails when the link's loss is reported
        data = frame.to_bytes()
        try:
            transport.send(data)
        except TransportError as exc:
            log.info("%s: send failed: %s", self.url, exc)
            return
        self.stats.frames_out += 1
        self.stats.bytes_out += len(data)
        if self._notifier.wants_traffic:
            self._notifier.traffic("out", frame, self.dialect.decode(frame))

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
        return self._notifier.subscribe(callback, ident)

    def on_traffic(self, callback: TrafficCallback) -> Callable[[], None]:
        """Call `callback(direction, frame, message)` for every frame in ("in") and out ("out"),
        decoded as on the wire (no sign mapping). Returns a remove function."""
        return self._notifier.on_traffic(callback)

    def commands(self) -> list[CommandSpec]:
        """The catalog commands this model supports."""
        return self.dialect.supported(self.model)

    # -- requests ---------------------------------------------------------------------------------

    def spec(self, ident: str) -> CommandSpec:
        """The catalog command `ident` (identifier or name), if this model supports it."""
        return self._builder.spec(ident)

    def build(self, ident: str, *, read: bool = False, dst: str | None = None, **values: Any) -> Frame:
        """The frame `request()` would send (values in API units and signs), validated."""
        return self._builder.build(ident, read=read, dst=dst, **values)

    async def _request(
        self,
        frame: Frame,
        *,
        timeout_s: float,
        retries: int,
        expect_reply: bool = True,
        exclusive: bool = False,
        fields: Mapping[str, Any] | None = None,
    ) -> Message | None:
        """Hand one frame to the engine and wait for what it decides."""
        if self._closed:
            raise TransportError(f"{self.url}: the client is closed")
        if self._engine is None or self._loop is None:
            raise TransportError(f"{self.url}: not open (await connect(...) first)")
        if not self.connected_transport:
            raise LinkLostError(f"{self.url}: the link is down ({self.link_state['reason']}); reconnecting")
        engine = self._engine
        tx: Transaction = engine.submit(
            frame, timeout_s=timeout_s, retries=retries, expect_reply=expect_reply, exclusive=exclusive, fields=fields
        )
        if not expect_reply:
            self._drive()
            return None
        tx.waiter = fut = self._loop.create_future()
        self._drive()
        try:
            return await fut  # type: ignore[no-any-return]
        except asyncio.CancelledError:
            engine.cancel(tx)
            self._drive()
            raise
        except TopGimbalError as exc:
            link = self._link
            if isinstance(exc, TimeoutError) and link is not None:
                if link.last_in is None:
                    raise type(exc)(
                        f"{exc}; nothing at all has come from {self.url} since the client opened: check the "
                        f"address, the model ({self.model.name}) and that the camera is on"
                    ) from None
                silent = link.silent_for()
                if silent >= timeout_s:
                    raise type(exc)(f"{exc}; nothing has come from the device for {silent:.1f} s") from None
            raise
