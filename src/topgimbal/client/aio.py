"""The asyncio client: a `Session` (matching) over a `Transport` (bytes), in user units.

Only this module and `transport/` touch asyncio. Everything the device sends goes through one
`FrameParser` per connection, then the session decides whether it answers a request; every frame
(answers included) then updates the state cache and reaches subscribers."""

from __future__ import annotations

import asyncio
import contextlib
import inspect
import logging
import math
import time
from collections.abc import AsyncGenerator, Awaitable, Callable, Generator, Mapping
from types import TracebackType
from typing import Any

from ..errors import DeviceError, FieldValueError, RequestTimeoutError, TransportError, UnsupportedError
from ..protocol import CommandSpec, DeviceModel, Dialect, Frame, FrameParser, Message, get_model, parse_frame
from ..protocol.frame import DEVICE_ADDRESSES
from ..transport import Transport, TransportURL, open_transport, parse_url
from .session import Key, LinkStats, Pending, Session
from .signs import map_message, map_values, resolve_signs
from .state import Attitude, SdCard, StateCache
from .traffic import TrafficLog

log = logging.getLogger("topgimbal.client")

MessageCallback = Callable[[Message], "Awaitable[None] | None"]
TrafficCallback = Callable[[str, Frame, "Message | None"], "Awaitable[None] | None"]

ATTITUDE_IDENTS = frozenset({"GAC", "GIC", "GIA"})
_END = object()


class AsyncClient:
    """A connection to one gimbal camera. Open with `await connect(url, model=...)`."""

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
        stop_repeats: int = 3,
        host_address: str | None = None,
    ) -> None:
        self.url = url
        self._url: TransportURL = parse_url(url)
        self.dialect: Dialect
        self.model: DeviceModel
        self.dialect, self.model = get_model(model)
        self.signs = resolve_signs(self.model, signs)
        self.timeout_s = timeout_s
        self.retries = retries
        self.echo_motion = echo_motion
        self.combined_motion = combined_motion
        self.stop_repeats = stop_repeats
        # TOPOTEK hosts are `P` on the network and `U` on a UART; SkyDroid is always `U`.
        self.host_address = host_address or (self.model.host_address if self._url.scheme != "serial" else "U")
        self.state = StateCache()
        self.stats = LinkStats()
        self._log_path = log_path
        self._late_window_s = late_window_s if late_window_s is not None else max(2.0, 2 * timeout_s)
        self._session: Session | None = None
        self._transport: Transport | None = None
        self._parser = FrameParser()
        self._loop: asyncio.AbstractEventLoop | None = None
        self._locks: dict[Key, asyncio.Lock] = {}
        self._subs: dict[str | None, list[MessageCallback]] = {}
        self._traffic: list[TrafficCallback] = []
        self._timer: asyncio.TimerHandle | None = None
        self._attitude_queues: set[asyncio.Queue[Any]] = set()
        self._stream_rate: float | None = None
        self._tasks: set[asyncio.Task[Any]] = set()
        self._traffic_log: TrafficLog | None = None
        self._closed = False
        self.cmd = CommandNamespace(self)

    # -- lifecycle -----------------------------------------------------------------------------

    async def open(self) -> AsyncClient:
        self._loop = asyncio.get_running_loop()
        self._session = Session(
            self.dialect, clock=self._loop.time, late_window_s=self._late_window_s, stats=self.stats
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
        """Stop streams started by this client (best effort), fail pending requests, close."""
        if self._closed:
            return
        if self._stream_rate is not None and self.connected:
            with contextlib.suppress(Exception):
                await self.stop_attitude_stream(timeout_s=min(self.timeout_s, 0.3), retries=0)
        self._closed = True
        self._shutdown(TransportError(f"{self.url}: the client was closed"))
        if self._transport is not None:
            await self._transport.close()
        for task in list(self._tasks):
            task.cancel()
        if self._traffic_log is not None:
            self._traffic_log.close()

    async def __aenter__(self) -> AsyncClient:
        return self

    async def __aexit__(
        self, et: type[BaseException] | None, e: BaseException | None, tb: TracebackType | None
    ) -> None:
        await self.close()

    @property
    def connected(self) -> bool:
        return self._transport is not None and self._transport.connected and not self._closed

    def _shutdown(self, error: Exception) -> None:
        self.stats.connected = False
        if self._timer is not None:
            self._timer.cancel()
            self._timer = None
        if self._session is not None:
            for p in self._session.fail_all(error):
                self._resolve(p)
        for q in list(self._attitude_queues):
            q.put_nowait(error)

    def _on_lost(self, exc: Exception | None) -> None:
        if self._closed:
            return
        err = exc if isinstance(exc, TransportError) else TransportError(f"{self.url}: link lost: {exc or 'closed'}")
        self._shutdown(err)

    # -- bytes in ------------------------------------------------------------------------------

    def _on_bytes(self, data: bytes) -> None:
        self.stats.bytes_in += len(data)
        items = self._parser.feed(data)
        if self._transport is not None and self._transport.is_datagram:
            items += self._parser.flush()  # a datagram ends its frames
        for item in items:
            if isinstance(item, Frame):
                self._on_frame(item)
            elif item.kind != "length_mismatch":
                self.stats.bad_frames += 1

    def _on_frame(self, frame: Frame) -> None:
        self.stats.frames_in += 1
        message = self.dialect.decode(frame)
        self._emit_traffic("in", frame, message)
        if frame.src not in DEVICE_ADDRESSES:
            return  # our own frames echoed by a loopback or a half-duplex line
        assert self._session is not None
        # Signs are mapped once, here: the session matches on the frame, never on field values,
        # so it can hold (and a request return) the message already in the API convention.
        api = map_message(message, self.signs)
        result = self._session.receive(api)
        if result.matched is not None:
            self._resolve(result.matched)
        if result.duplicate:
            return
        self._update_state(api)
        self._dispatch(api)
        self._arm_timer()

    # -- bytes out -----------------------------------------------------------------------------

    def _send_frame(self, frame: Frame) -> None:
        if self._transport is None or not self.connected:
            raise TransportError(f"{self.url}: not connected")
        data = frame.to_bytes()
        self._transport.send(data)
        self.stats.frames_out += 1
        self.stats.bytes_out += len(data)
        if self._traffic:
            self._emit_traffic("out", frame, self.dialect.decode(frame))

    def _arm_timer(self) -> None:
        assert self._loop is not None and self._session is not None
        deadline = self._session.next_deadline()
        if self._timer is not None:
            if deadline is not None and self._timer.when() == deadline:
                return
            self._timer.cancel()
            self._timer = None
        if deadline is not None:
            self._timer = self._loop.call_at(deadline, self._on_timer)

    def _on_timer(self) -> None:
        self._timer = None
        assert self._session is not None
        for p, action in self._session.expire():
            if action == "retry":
                try:
                    self._send_frame(p.frame)
                except TransportError as exc:
                    self._session.cancel(p, exc)
                    self._resolve(p)
                    continue
                self._session.sent(p)
            else:
                self._resolve(p)
        self._arm_timer()

    def _resolve(self, p: Pending) -> None:
        fut = p.waiter
        if fut is None or fut.done():
            return
        if p.error is not None:
            fut.set_exception(p.error)
        else:
            fut.set_result(p.reply)

    async def _transact(self, frame: Frame, *, timeout_s: float, retries: int, expect_reply: bool) -> Message | None:
        assert self._loop is not None and self._session is not None
        if self._closed:
            raise TransportError(f"{self.url}: the client is closed")
        session = self._session
        if not expect_reply:
            p = session.open(frame, timeout_s=timeout_s, retries=0, expect_reply=False)
            self._send_frame(frame)
            session.sent(p)
            return None
        key = session.key_of(frame)
        lock = self._locks.get(key)
        if lock is None:
            lock = self._locks[key] = asyncio.Lock()
        async with lock:  # one outstanding request per (identifier, destination)
            p = session.open(frame, timeout_s=timeout_s, retries=retries)
            p.waiter = self._loop.create_future()
            try:
                self._send_frame(frame)
                session.sent(p)
                self._arm_timer()
                reply: Message | None = await p.waiter
            except asyncio.CancelledError:
                session.cancel(p)
                raise
            except TransportError:
                session.cancel(p)
                raise
            return reply

    # -- generic requests ----------------------------------------------------------------------

    def _spec(self, ident: str) -> CommandSpec:
        spec = self.dialect.command(ident)
        if not self.dialect.supports(self.model, spec.ident):
            raise UnsupportedError(f"the {self.model.name} does not support {spec.ident} ({spec.title})")
        return spec

    def build(self, ident: str, *, read: bool = False, dst: str | None = None, **values: Any) -> Frame:
        """The frame `request()` would send (values in API units and signs), validated."""
        spec = self._spec(ident)
        self.dialect.check_values(self.model, spec.ident, values)
        wire = map_values(spec, values, self.signs)
        return self.dialect.encode(spec.ident, read=read, src=self.host_address, dst=dst, **wire)

    async def request(
        self,
        ident: str,
        *,
        read: bool = False,
        timeout_s: float | None = None,
        retries: int | None = None,
        wait_reply: bool | None = None,
        dst: str | None = None,
        **values: Any,
    ) -> Message:
        """Send one catalog command and return the device's answer (fields in API units).

        Validation (model support, value ranges) happens before anything is sent. Retries are
        used only when the frame is idempotent (queries, absolute set-points). Raises
        RequestTimeoutError, DeviceError (ERE) or TransportError."""
        frame = self.build(ident, read=read, dst=dst, **values)
        spec = self.dialect.command(frame.ident)
        if wait_reply is None:
            wait_reply = read or (spec.echo and (self.echo_motion or not spec.motion))
        n = self.retries if retries is None else retries
        if not spec.is_idempotent(frame):
            n = 0  # toggles, relative steps and photos act again on every copy: never retried
        reply = await self._transact(
            frame, timeout_s=self.timeout_s if timeout_s is None else timeout_s, retries=n, expect_reply=wait_reply
        )
        if reply is None:
            return Message(frame, spec, None, None, "sent without waiting for a reply")
        return reply  # already in the API convention (mapped on arrival)

    async def send_raw(
        self, frame: Frame | str | bytes, *, wait_reply: bool = True, timeout_s: float | None = None
    ) -> Message | None:
        """Send a frame as given (no validation, no sign mapping, no retries); return the reply."""
        if not isinstance(frame, Frame):
            raw = frame.encode("latin-1") if isinstance(frame, str) else frame
            frame = parse_frame(raw.strip())
        reply = await self._transact(
            frame, timeout_s=self.timeout_s if timeout_s is None else timeout_s, retries=0, expect_reply=wait_reply
        )
        # Replies are held in the API convention; a raw exchange shows the wire's values (the
        # sign map is its own inverse).
        return None if reply is None else map_message(reply, self.signs)

    # -- subscriptions -------------------------------------------------------------------------

    def subscribe(self, callback: MessageCallback, ident: str | None = None) -> Callable[[], None]:
        """Call `callback(message)` for every frame from the device (or only `ident` frames),
        answers included, fields in API units. Sync or async; returns an unsubscribe function."""
        key = ident.upper() if ident else None
        self._subs.setdefault(key, []).append(callback)

        def unsubscribe() -> None:
            with contextlib.suppress(ValueError, KeyError):
                self._subs[key].remove(callback)

        return unsubscribe

    def on_traffic(self, callback: TrafficCallback) -> Callable[[], None]:
        """Call `callback(direction, frame, message)` for every frame in ("in") and out ("out"),
        decoded as on the wire (no sign mapping)."""
        self._traffic.append(callback)

        def remove() -> None:
            with contextlib.suppress(ValueError):
                self._traffic.remove(callback)

        return remove

    def _call_guarded(self, cb: Callable[..., Any], *args: Any) -> None:
        try:
            result = cb(*args)
        except Exception:
            log.exception("subscriber %r failed", cb)
            return
        if inspect.isawaitable(result):
            task = asyncio.ensure_future(result)
            self._tasks.add(task)
            task.add_done_callback(self._task_done)

    def _task_done(self, task: asyncio.Task[Any]) -> None:
        self._tasks.discard(task)
        if not task.cancelled() and task.exception() is not None:
            log.error("async subscriber failed", exc_info=task.exception())

    def _dispatch(self, message: Message) -> None:
        for cb in [*self._subs.get(None, ()), *self._subs.get(message.ident, ())]:
            self._call_guarded(cb, message)

    def _emit_traffic(self, direction: str, frame: Frame, message: Message | None) -> None:
        for cb in list(self._traffic):
            self._call_guarded(cb, direction, frame, message)

    # -- state cache ---------------------------------------------------------------------------

    def _update_state(self, m: Message) -> None:
        f = m.fields
        if f is None or m.is_error:
            return
        ident = m.ident
        st = self.state
        if ident in ATTITUDE_IDENTS and "yaw_deg" in f:
            att = Attitude(f["yaw_deg"], f["pitch_deg"], f["roll_deg"], time.monotonic(), time.time(), ident)
            st.attitude = att
            for q in list(self._attitude_queues):
                q.put_nowait(att)
        elif ident == "REC":
            value = f.get("state", f.get("action"))
            if value in ("recording", "started", "start"):
                st.set("recording", True)
            elif value in ("stopped", "stop"):
                st.set("recording", False)
        elif ident == "SDC":
            if "total_mb" in f:
                total, remaining = f["total_mb"], f["remaining_mb"]
                st.set("sd", SdCard(bool(total), remaining if total else None, total or None))
        elif ident in ("ZMP", "MUL") and "magnification_x" in f:
            st.set("zoom", f["magnification_x"])
        elif ident == "DZM" and m.frame.rw == "r":
            st.set("zoom", f.get("zoom", f.get("visible_zoom_x")))
        elif ident in ("LRF", "SLR") and "distance_m" in f:
            st.set("range_m", f["distance_m"])
        elif ident in ("VER", "VSN") and "version" in f:
            st.set("version", f["version"])
        elif ident == "PA2":
            st.set("model_name", f.get("model"))
        elif ident == "TMP" and f:
            st.set("temperature", f)
        elif ident == "CAP" and "file_index" in f:
            st.set("last_photo_index", f["file_index"])

    # -- telemetry -----------------------------------------------------------------------------

    async def attitude_stream(self, rate_hz: float = 50, **kw: Any) -> None:
        """Ask the device to stream its attitude (SkyDroid: at `rate_hz`, 1..100; TOPOTEK: on,
        at the device's own rate, which `attitude()` decimates)."""
        if "rate_hz" in self._request_fields("GAA"):
            rate = round(rate_hz)
            if not 1 <= rate <= 100:
                raise FieldValueError("rate_hz", rate_hz, "1..100 Hz")
            await self.request("GAA", rate_hz=rate, **kw)
        else:
            await self.request("GAA", state="on", **kw)
        self._stream_rate = rate_hz

    async def stop_attitude_stream(self, **kw: Any) -> None:
        if "rate_hz" in self._request_fields("GAA"):
            await self.request("GAA", rate_hz=0, **kw)
        else:
            await self.request("GAA", state="off", **kw)
        self._stream_rate = None

    def _request_fields(self, ident: str) -> set[str]:
        spec = self._spec(ident)
        return {f.name for form in spec.forms_for("w", "request") for f in form.fields}

    async def attitude(self, rate_hz: float = 50) -> AsyncGenerator[Attitude, None]:
        """Attitude samples as they arrive, at most `rate_hz`. Starts the device's stream if no
        stream is running and stops it when the last iterator ends."""
        q: asyncio.Queue[Any] = asyncio.Queue()
        self._attitude_queues.add(q)
        started = False
        try:
            if self._stream_rate is None or self._stream_rate < rate_hz:
                await self.attitude_stream(rate_hz)
                started = True
            min_gap = 1.0 / rate_hz * 0.9 if rate_hz > 0 else 0.0  # 10 % slack: device clocks drift
            last = -math.inf
            while True:
                item = await q.get()
                if isinstance(item, Exception):
                    raise item
                if item.t - last < min_gap:
                    continue
                last = item.t
                yield item
        finally:
            self._attitude_queues.discard(q)
            if started and not self._attitude_queues and self.connected:
                with contextlib.suppress(Exception):
                    await self.stop_attitude_stream(timeout_s=min(self.timeout_s, 0.3), retries=0)

    async def get_attitude(self, *, earth: bool = False) -> Attitude:
        """Query the attitude once (TOPOTEK `earth=True`: the gyro, earth-frame reading)."""
        m = await self.request("GIC" if earth else "GAC", read=True)
        f = self._fields(m)
        return Attitude(f["yaw_deg"], f["pitch_deg"], f["roll_deg"], time.monotonic(), time.time(), m.ident)

    async def wait_attitude(self, *, newer_than: float = 0.0, timeout_s: float | None = None) -> Attitude:
        """The next attitude sample from the stream (arrived after `newer_than`, monotonic)."""
        q: asyncio.Queue[Any] = asyncio.Queue()
        self._attitude_queues.add(q)

        async def next_sample() -> Attitude:
            while True:
                item = await q.get()
                if isinstance(item, Exception):
                    raise item
                if item.t > newer_than:
                    return item  # type: ignore[no-any-return]

        try:
            return await asyncio.wait_for(next_sample(), timeout_s or self.timeout_s * 3)
        except asyncio.TimeoutError:
            raise RequestTimeoutError("no attitude sample arrived") from None
        finally:
            self._attitude_queues.discard(q)

    # -- motion --------------------------------------------------------------------------------

    def _check_axis(self, axis: str, value: float | None) -> None:
        if value is None:
            return
        lo, hi = getattr(self.model, f"{axis}_range_deg")
        if not isinstance(value, (int, float)) or isinstance(value, bool) or not lo <= value <= hi:
            raise FieldValueError(f"{axis}_deg", value, f"{lo:g}..{hi:g} degrees on the {self.model.name}")

    async def set_angles(
        self,
        yaw_deg: float | None = None,
        pitch_deg: float | None = None,
        roll_deg: float | None = None,
        *,
        speed_deg_s: float | None = None,
        frame: str = "body",
    ) -> None:
        """Move to absolute angles (degrees, API convention). `frame="earth"` uses TOPOTEK's gyro
        (GI*) commands. Every value is checked before the first frame goes out."""
        if frame not in ("body", "earth"):
            raise FieldValueError("frame", frame, "'body' or 'earth'")
        prefix = "GI" if frame == "earth" else "GA"
        if frame == "earth" and "GIY" not in self.dialect.commands:
            raise UnsupportedError(f"the {self.model.name} has no earth-frame angle commands")
        for axis, v in (("yaw", yaw_deg), ("pitch", pitch_deg), ("roll", roll_deg)):
            self._check_axis(axis, v)
        sp: dict[str, Any] = {} if speed_deg_s is None else {"speed_deg_s": speed_deg_s}
        frames: list[tuple[str, dict[str, Any]]] = []
        if yaw_deg is not None and pitch_deg is not None and self.combined_motion:
            both: dict[str, Any] = {"yaw_deg": yaw_deg, "pitch_deg": pitch_deg}
            if speed_deg_s is not None:
                both.update(yaw_speed_deg_s=speed_deg_s, pitch_speed_deg_s=speed_deg_s)
            frames.append((prefix + "M", both))
        else:
            if yaw_deg is not None:
                frames.append((prefix + "Y", {"yaw_deg": yaw_deg, **sp}))
            if pitch_deg is not None:
                frames.append((prefix + "P", {"pitch_deg": pitch_deg, **sp}))
        if roll_deg is not None:
            frames.append((prefix + "R", {"roll_deg": roll_deg, **sp}))
        for ident, values in frames:
            self.build(ident, **values)  # validate all before sending any
        for ident, values in frames:
            await self.request(ident, **values)

    async def rates(self, yaw_deg_s: float = 0, pitch_deg_s: float = 0, roll_deg_s: float = 0, **kw: Any) -> None:
        """Turn at constant rates (deg/s, API convention) until told otherwise."""
        frames: list[tuple[str, dict[str, Any]]] = []
        if roll_deg_s and "YPR" in self.dialect.commands:
            frames.append(
                ("YPR", {"yaw_rate_deg_s": yaw_deg_s, "pitch_rate_deg_s": pitch_deg_s, "roll_rate_deg_s": roll_deg_s})
            )
        elif self.combined_motion:
            frames.append(("GSM", {"yaw_rate_deg_s": yaw_deg_s, "pitch_rate_deg_s": pitch_deg_s}))
            if roll_deg_s:
                frames.append(("GSR", {"roll_rate_deg_s": roll_deg_s}))
        else:
            frames += [("GSY", {"yaw_rate_deg_s": yaw_deg_s}), ("GSP", {"pitch_rate_deg_s": pitch_deg_s})]
            if roll_deg_s:
                frames.append(("GSR", {"roll_rate_deg_s": roll_deg_s}))
        for ident, values in frames:
            self.build(ident, **values)
        for ident, values in frames:
            await self.request(ident, **values, **kw)

    async def stop(self) -> None:
        """Stop all motion the way real devices need: zero rates sent several times (a lost stop
        leaves the gimbal turning), then PTZ stop, answered."""
        zero = self.build("GSM", yaw_rate_deg_s=0, pitch_rate_deg_s=0)
        for _ in range(max(0, self.stop_repeats - 1)):
            await self._transact(zero, timeout_s=self.timeout_s, retries=0, expect_reply=False)
        await self.rates(0, 0, 0)
        await self.request("PTZ", action="stop")

    async def center(self) -> None:
        await self.request("PTZ", action="center")

    async def set_mode(self, mode: str) -> None:
        """`follow` (the camera follows the vehicle's heading) or `lock` (holds its heading)."""
        if mode not in ("follow", "lock"):
            raise FieldValueError("mode", mode, "'follow' or 'lock'")
        await self.request("PTZ", action=mode)
        self.state.set("mode", mode)

    async def point(
        self,
        yaw_deg: float,
        pitch_deg: float,
        *,
        tolerance_deg: float = 0.5,
        timeout_s: float | None = None,
        speed_deg_s: float | None = None,
        poll_s: float = 0.05,
    ) -> Attitude:
        """Move to (yaw, pitch) and return once the attitude feedback is within `tolerance_deg`
        on both axes; RequestTimeoutError otherwise. The default timeout allows for the slew."""
        self._check_axis("yaw", yaw_deg)
        self._check_axis("pitch", pitch_deg)
        now_att = self.state.attitude
        if now_att is None or time.monotonic() - now_att.t > 1.0:
            with contextlib.suppress(RequestTimeoutError):
                now_att = await self.get_attitude()
        if timeout_s is None:
            dist = 180.0 if now_att is None else max(abs(yaw_deg - now_att.yaw_deg), abs(pitch_deg - now_att.pitch_deg))
            speed = speed_deg_s or min(9.9, self.model.max_rate_deg_s)
            timeout_s = dist / max(speed, 0.5) * 1.5 + 3.0
        loop = asyncio.get_running_loop()
        deadline = loop.time() + timeout_s
        await self.set_angles(yaw_deg, pitch_deg, speed_deg_s=speed_deg_s)
        last: Attitude | None = None
        while loop.time() < deadline:
            streaming = self._stream_rate is not None
            try:
                if streaming:
                    last = await self.wait_attitude(
                        newer_than=last.t if last else 0.0, timeout_s=max(0.05, deadline - loop.time())
                    )
                else:
                    last = await self.get_attitude()
            except RequestTimeoutError:
                continue
            if abs(last.yaw_deg - yaw_deg) <= tolerance_deg and abs(last.pitch_deg - pitch_deg) <= tolerance_deg:
                return last
            if not streaming:
                await asyncio.sleep(min(poll_s, max(0.0, deadline - loop.time())))
        where = f" (last yaw {last.yaw_deg:.2f}, pitch {last.pitch_deg:.2f})" if last else ""
        raise RequestTimeoutError(f"did not reach yaw {yaw_deg:g}, pitch {pitch_deg:g} within {timeout_s:.1f} s{where}")

    def rate_control(self, interval_s: float = 0.1) -> RateKeepAlive:
        """A joystick helper: `async with cam.rate_control() as joy: joy.set(yaw_deg_s=10)`
        re-sends the current rates every `interval_s` (fire-and-forget) and stops on exit."""
        return RateKeepAlive(self, interval_s)

    # -- camera --------------------------------------------------------------------------------

    async def photo(self, **values: Any) -> Message:
        """Take one photo (never retried: a retry could take a second one)."""
        return await self.request("CAP", **values)

    async def start_recording(self) -> None:
        await self.request("REC", action="start")
        self.state.set("recording", True)

    async def stop_recording(self) -> None:
        await self.request("REC", action="stop")
        self.state.set("recording", False)

    async def toggle_recording(self) -> None:
        await self.request("REC", action="toggle")

    async def recording(self) -> bool:
        m = await self.request("REC", read=True)
        rec = self._fields(m).get("state") == "recording"
        self.state.set("recording", rec)
        return rec

    async def sd_card(self) -> SdCard:
        spec = self._spec("SDC")
        names = {f.name for form in spec.forms_for("r", "response") for f in form.fields}
        if "total_mb" in names:
            f = self._fields(await self.request("SDC", read=True))
            total, remaining = f["total_mb"], f["remaining_mb"]
            sd = SdCard(bool(total), remaining if total else None, total or None)
        else:  # TOPOTEK: one query per figure, NNNNN = no card
            remaining = self._fields(await self.request("SDC", read=True, which="remaining"))["capacity_mb"]
            total = self._fields(await self.request("SDC", read=True, which="total"))["capacity_mb"]
            sd = SdCard(remaining is not None and total is not None, remaining, total)
        self.state.set("sd", sd)
        return sd

    async def zoom(self, action_or_level: str | float) -> None:
        """`"in"`, `"out"`, `"stop"` (continuous optical zoom), or a magnification: optical
        (TOPOTEK MUL) or digital (SkyDroid DZM 1..4x)."""
        if isinstance(action_or_level, str) and not _is_number(action_or_level):
            action = {"in": "zoom_in", "out": "zoom_out"}.get(action_or_level, action_or_level)
            await self.request("ZMC", action=action)
            return
        level = float(action_or_level)
        if self.dialect.supports(self.model, "MUL"):
            await self.request("MUL", magnification_x=level)
        else:
            await self.digital_zoom(level)
        self.state.set("zoom", level)

    async def digital_zoom(self, level_or_action: str | float, *, lens: str = "visible") -> None:
        spec = self._spec("DZM")
        names = {f.name for form in spec.forms_for("w", "request") for f in form.fields}
        value: Any = level_or_action
        if "lens" in names:
            if isinstance(value, str) and not _is_number(value):
                value = {"in": "step_in", "out": "step_out"}.get(value, value)
            else:
                value = float(value)
            await self.request("DZM", lens=lens, zoom=value)
        else:
            if isinstance(value, str) and not _is_number(value):
                value = {"in": "zoom_in", "out": "zoom_out"}.get(value, value)
            else:
                f = float(value)
                if f != int(f) or not 1 <= f <= 4:
                    raise FieldValueError("zoom", level_or_action, "1, 2, 3 or 4 (x) on the " + self.model.name)
                value = f"{int(f)}x"
            await self.request("DZM", zoom=value)

    async def focus(self, action: str) -> None:
        """`"plus"`, `"minus"`, `"stop"`, `"auto"`, `"manual"` (FCC)."""
        action = {"plus": "focus_plus", "+": "focus_plus", "minus": "focus_minus", "-": "focus_minus"}.get(
            action, action
        )
        await self.request("FCC", action=action)

    async def palette(self, name: str | None = None) -> str:
        """Read (no argument) or set the thermal palette."""
        if name is None:
            return str(self._fields(await self.request("IMG", read=True))["palette"])
        await self.request("IMG", palette=name)
        return name

    async def thermal(self, setting: str, value: Any = None) -> Any:
        """Read or set one thermal setting by catalog name or identifier: `palette`, `scene`
        (TSM), `shutter` (TAS), `detail`, `brightness`, `contrast`, `spatial_denoise`,
        `temporal_denoise`, `gamma`, `range` (TMR)."""
        aliases = {"palette": "IMG", "scene": "TSM", "shutter": "TAS", "range": "TMR"}
        ident = aliases.get(setting) or _thermal_ident(self.dialect, setting)
        spec = self._spec(ident)
        form = spec.forms_for("w" if value is not None else "r", "request" if value is not None else "response")
        if not form or not form[0].fields:
            raise UnsupportedError(
                f"{ident} cannot be {'set' if value is not None else 'read'} on the {self.model.name}"
            )
        fname = form[0].fields[-1].name
        if value is None:
            return self._fields(await self.request(ident, read=True))[fname]
        await self.request(ident, **{fname: value})
        return value

    async def version(self) -> str:
        ident = "VER" if self.dialect.name == "skydroid" else "VSN"
        return str(self._fields(await self.request(ident, read=True))["version"])

    async def identify(self, *, timeout_s: float | None = None) -> dict[str, Any]:
        """Ask the device who it is (SkyDroid VER; TOPOTEK VSN and PA2). Returns what answered:
        `{"dialect", "model", "version", "model_name"}`; unanswered parts are None."""
        t = timeout_s or self.timeout_s
        out: dict[str, Any] = {
            "dialect": self.dialect.name,
            "model": self.model.name,
            "version": None,
            "model_name": None,
        }
        with contextlib.suppress(RequestTimeoutError, DeviceError, UnsupportedError):
            out["version"] = await asyncio.wait_for(self.version(), t * 3)
        if self.dialect.name == "topotek":
            with contextlib.suppress(RequestTimeoutError, DeviceError, UnsupportedError):
                out["model_name"] = self._fields(await self.request("PA2", read=True, timeout_s=t))["model"]
                self.state.set("model_name", out["model_name"])
        return out

    async def detect_model(self, *, timeout_s: float = 0.5) -> str | None:
        """Which dialect the device speaks, by asking what only one dialect answers: TOPOTEK PA2
        (model name), then SkyDroid VER. Returns a model name, or None if nothing answered."""
        from ..protocol import get_dialect

        topo = get_dialect("topotek")
        probe = topo.encode("PA2", read=True, src=self.host_address if self.host_address in "UP" else "U")
        with contextlib.suppress(RequestTimeoutError, DeviceError):
            m = await self._transact(probe, timeout_s=timeout_s, retries=1, expect_reply=True)
            if m is not None:
                return "SIP"
        sky = get_dialect("skydroid")
        with contextlib.suppress(RequestTimeoutError, DeviceError):
            m = await self._transact(
                sky.encode("VER", read=True, src="U"), timeout_s=timeout_s, retries=1, expect_reply=True
            )
            if m is not None:
                return self.model.name if self.dialect.name == "skydroid" else "C12"
        return None

    async def range(self, *, timeout_s: float | None = None) -> float | None:
        """One laser range measurement in metres (None: the rangefinder reported a failure)."""
        if self.dialect.supports(self.model, "SLR") and "SLR" in self.dialect.commands:
            d = self._fields(await self.request("SLR", read=True, timeout_s=timeout_s))["distance_m"]
            self.state.set("range_m", d)
            return d  # type: ignore[no-any-return]
        if self.model.lrf_range_m is None or not self.dialect.supports(self.model, "LRF"):
            raise UnsupportedError(f"the {self.model.name} has no laser rangefinder")
        loop = asyncio.get_running_loop()
        result: asyncio.Future[Any] = loop.create_future()

        def on_lrf(m: Message) -> None:
            if m.fields and "distance_m" in m.fields and not result.done():
                result.set_result(m.fields["distance_m"])

        unsubscribe = self.subscribe(on_lrf, "LRF")
        try:
            await self.request("LRF", action="single", timeout_s=timeout_s)
            try:
                d = await asyncio.wait_for(result, timeout_s or self.timeout_s * 3)
            except TimeoutError:
                raise RequestTimeoutError("the rangefinder sent no result") from None
        finally:
            unsubscribe()
        return d  # type: ignore[no-any-return]

    async def network(self) -> dict[str, str | None]:
        """The camera's network settings (IPV, GTW, and DNS/BNS where the dialect has them)."""
        out: dict[str, str | None] = {}
        for ident, name in (("IPV", "ip"), ("GTW", "gateway"), ("DNS", "dns"), ("BNS", "backup_dns")):
            if ident in self.dialect.commands and self.dialect.supports(self.model, ident):
                out[name] = self._fields(await self.request(ident, read=True))["address"]
        return out

    async def set_network(
        self, ip: str | None = None, gateway: str | None = None, dns: str | None = None, backup_dns: str | None = None
    ) -> None:
        """Change network settings. After changing `ip` the camera answers at the new address."""
        plan = [(i, v) for i, v in (("IPV", ip), ("GTW", gateway), ("DNS", dns), ("BNS", backup_dns)) if v is not None]
        for ident, v in plan:
            self.build(ident, address=v)
        for ident, v in plan:
            await self.request(ident, address=v)

    def video_url(self, lens: str = "visible", *, host: str | None = None, port: int | None = None) -> str:
        """RTSP URL of a lens's stream (the model's documented port and path) at the camera's
        address: the control URL's host unless `host` says otherwise. See docs/video.md."""
        from ..video.lens import host_of, video_url  # the per-model stream table (pure)

        return video_url(self.model.name, host or host_of(self.url), lens, port=port)

    # -- helpers -------------------------------------------------------------------------------

    @staticmethod
    def _fields(m: Message) -> dict[str, Any]:
        if m.fields is None:
            raise DeviceError(f"cannot read the device's answer {m.frame.text()}: {m.error}")
        return m.fields

    def commands(self) -> list[CommandSpec]:
        """The catalog commands this model supports."""
        return self.dialect.supported(self.model)


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

    async def __call__(self, **values: Any) -> Message:
        return await self.client.request(self.spec.ident, **values)

    async def read(self, **values: Any) -> Message:
        return await self.client.request(self.spec.ident, read=True, **values)


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
        self.client.build("GSM", yaw_rate_deg_s=yaw_deg_s, pitch_rate_deg_s=pitch_deg_s)  # validate now
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


def _is_number(text: str) -> bool:
    try:
        float(text)
    except ValueError:
        return False
    return True


def _thermal_ident(dialect: Dialect, setting: str) -> str:
    for spec in dialect.commands.values():
        if spec.name in (setting, f"thermal_{setting}") or spec.ident == setting.upper():
            return spec.ident
    raise UnsupportedError(f"no thermal setting {setting!r} in the {dialect.name} dialect")


class _Connector:
    """What `connect()` returns: awaitable (an open client) and an async context manager."""

    def __init__(self, client: AsyncClient) -> None:
        self._client = client

    def __await__(self) -> Generator[Any, None, AsyncClient]:
        return self._client.open().__await__()

    async def __aenter__(self) -> AsyncClient:
        return await self._client.open()

    async def __aexit__(
        self, et: type[BaseException] | None, e: BaseException | None, tb: TracebackType | None
    ) -> None:
        await self._client.close()


def connect(
    url: str,
    model: str = "C12",
    *,
    timeout_s: float = 1.0,
    retries: int = 2,
    signs: Mapping[str, int] | None = None,
    log_path: str | None = None,
    **options: Any,
) -> _Connector:
    """Open a client: `cam = await connect(url, model="C12")` or
    `async with connect(url, model="SIP") as cam: ...`. Options: echo_motion, combined_motion,
    late_window_s, stop_repeats, host_address (see AsyncClient)."""
    return _Connector(
        AsyncClient(url, model, timeout_s=timeout_s, retries=retries, signs=signs, log_path=log_path, **options)
    )
