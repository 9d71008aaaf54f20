"""The sans-I/O virtual camera: bytes in, bytes out, time from a clock.

`Device.receive(peer, data)` takes what a host sent (one datagram, or a chunk of a byte stream)
and returns the frames to send back, each addressed to a peer. `Device.tick()` returns what is due
on its own (attitude streams, ZMP after a zoom, rangefinder results, late answers). Peers are
opaque hashable objects owned by the servers; the device only uses them as addresses and
subscription keys.

Rules (both documents, §2.3): a control command is echoed with swapped addresses; a query is
answered with data; an unknown identifier, malformed data, or a command the model does not
support gets the error frame; a frame with a bad checksum is ignored. The model profile's quirks
(`protocol.QUIRKS`, switched by `quirks.resolve`) bend these rules the way real firmware does.

The device dispatches on a handler table (`handlers.handler_table(dialect)`, or the caller's),
precomputed per model into one entry per identifier, so a request costs one dictionary lookup
before its handler runs. Handlers see only `context.SimState`.
"""

from __future__ import annotations

import heapq
import logging
import math
from collections.abc import Hashable, Mapping
from dataclasses import dataclass, field, replace
from datetime import datetime
from typing import Any

from ..errors import TopGimbalError
from ..protocol import REQUEST, DeviceModel, Diagnostic, Frame, FrameParser, get_dialect, get_model
from ..protocol.frame import DEVICE_ADDRESSES
from ..protocol.signs import flip, resolve_signs
from . import quirks as quirk_table
from .clock import Clock, MonotonicClock
from .context import Handler, RefusedError, Reply, Request, SimState, StateView, new_state
from .entries import Entry, build_entries
from .handlers import handler_table
from .handlers.lens import zoom_report
from .tracker import TRACK_STEP_S

# TOPOTEK's GAA / GIA switch a stream on without a rate; this is the simulator's (documented) rate.
TOPOTEK_STREAM_HZ = 10.0
MAX_RECEIVED = 10000
STREAM_CATCH_UP_S = 1.0
MOTOR_STEP_S = 0.05  # while motors run, wake this often so end-of-travel reports go out on time
FRAME_OVERHEAD = 12  # header, addresses, length, control, identifier, checksum
MAX_CACHED_ANSWERS = 512  # encoded answers kept for repeated queries (cleared when full)

log = logging.getLogger("topgimbal.sim")


@dataclass(slots=True)
class Outgoing:
    peer: Hashable
    data: bytes
    reply: bool = True  # an answer to a request (late-reply faults apply), not a stream frame


@dataclass
class Device(StateView):
    model_name: str | DeviceModel
    seed: int = 0
    clock: Clock = field(default_factory=MonotonicClock)
    quirk_overrides: Mapping[str, quirk_table.Override] | None = None
    topotek_stream_hz: float | None = None  # rate of on / off streams; None: the profile's
    handlers: Mapping[str, Handler] | None = None  # replaces / adds to the dialect's table

    def __post_init__(self) -> None:
        dialect, model = get_model(self.model_name)
        self.model_name = model.name
        self.quirks, self.quirk_values = quirk_table.resolve(model, self.quirk_overrides)
        if "speed_unit_deg_s" in model.dialect_options and not self.quirks["speed_unit"]:
            options = {k: v for k, v in model.dialect_options.items() if k != "speed_unit_deg_s"}
            dialect = get_dialect(model.dialect, **options, destinations=dict(model.destinations) or None)
        self.dialect, self.model = dialect, model
        signs = resolve_signs(model) if self.quirks["wire_signs"] else resolve_signs(_no_signs(model))
        self.signs = signs
        self.state: SimState = new_state(
            model, dialect, signs=signs, quirks=self.quirks, seed=self.seed, stream_hz=self.topotek_stream_hz
        )
        self.table = handler_table(dialect, self.handlers)
        self._entries: dict[str, Entry] = build_entries(dialect, model, self.table, self.quirks)
        self.received: list[Frame] = []
        self.dropped: dict[str, int] = {}  # frames a quirk dropped, by quirk name
        self.errors = 0  # handler failures answered with the error frame
        self._parsers: dict[Hashable, FrameParser] = {}
        self._last = self.clock.now()
        self.state.camera.booted_at = self._last
        self._late: list[tuple[float, int, Outgoing]] = []
        self._late_seq = 0
        self._last_command: float | None = None
        q = self.quirks
        self._max_frame = model.max_frame_bytes if q["frame_size_limit"] else None
        self._gap_s = model.min_command_gap_s if q["command_pacing"] else 0.0
        self._lowercase, self._crlf, self._ver_length = q["lowercase_header"], q["crlf"], q["ver_wrong_length"]
        self._errors: dict[tuple[str, str], Frame] = {}
        self._error_ident = dialect.require_role("error").ident  # the protocol's ERE
        self._answers: dict[Hashable, bytes] = {}
        self._versions = frozenset(i for i, e in self._entries.items() if e.spec.role == "version")

    # -- time ------------------------------------------------------------------------------------

    def sync(self, t: float | None = None) -> None:
        """Bring physics and motors up to time `t` (never backwards)."""
        t = self.clock.now() if t is None else t
        if t <= self._last:
            return
        state = self.state
        if state.coast_until is not None and state.coast_until <= t:
            # A coasting stop takes now: move up to that moment, then stop.
            if state.coast_until > self._last:
                self._advance(state.coast_until - self._last, self._last)
                self._last = state.coast_until
            for axis in state.coast_axes:
                if state.gimbal.axis(axis).mode == "rate":
                    state.gimbal.rate(axis, 0.0)
            state.coast_until, state.coast_axes = None, ()
        self._advance(t - self._last, self._last)
        self._last = t

    def _advance(self, dt: float, t0: float) -> None:
        state = self.state
        tracker = state.tracker
        if tracker is not None and tracker.state == "tracking":
            # The camera's tracker looks once a frame and sets the gimbal's rates in between.
            n = max(1, math.ceil(dt / TRACK_STEP_S - 1e-9))
            h = dt / n
            for i in range(n):
                t = t0 + i * h
                if tracker.state == "tracking":
                    tracker.update(t, state.gimbal, state.tracking_hfov_deg(), state.target_views(t))
                    state.camera.tracking = tracker.state
                state.gimbal.advance(h)
        else:
            state.gimbal.advance(dt)
        state.camera.advance(dt)

    @property
    def now(self) -> float:
        return self._last

    def camera_time(self) -> datetime | None:
        """The camera's clock now: what a host set with TIM / UTC, moved on; before that, on a
        camera without a clock (no_clock quirk), 1970-01-01 plus the time since power-on."""
        return self.state.camera.clock(self._last, has_clock=not self.quirks["no_clock"])

    # -- input -----------------------------------------------------------------------------------

    def receive(self, peer: Hashable, data: bytes, *, datagram: bool = True) -> list[Outgoing]:
        """Handle what `peer` sent. A datagram is complete in itself (leftover bytes are dropped);
        a stream chunk may end mid-frame (the rest waits for the next chunk)."""
        parser = self._parsers.get(peer)
        if parser is None:
            parser = self._parsers[peer] = FrameParser(max_data_length=0xFF)
        items = parser.feed_datagram(data) if datagram else parser.feed(data)
        if len(items) == 1 and not isinstance(items[0], Diagnostic):
            return self.handle(peer, items[0])
        out: list[Outgoing] = []
        for item in items:
            if not isinstance(item, Diagnostic):  # bad checksum / garbage: ignored, as a device does
                out.extend(self.handle(peer, item))
        return out

    def _drop(self, quirk: str) -> list[Outgoing]:
        self.dropped[quirk] = self.dropped.get(quirk, 0) + 1
        return []

    def handle(self, peer: Hashable, frame: Frame) -> list[Outgoing]:
        if frame.dst not in DEVICE_ADDRESSES or frame.src in DEVICE_ADDRESSES:
            return []  # not addressed to a device (a reply looping back): nothing to do
        if self._max_frame is not None and FRAME_OVERHEAD + len(frame.data) > self._max_frame:
            return self._drop("frame_size_limit")
        entry = self._entries.get(frame.ident)
        if entry is not None:
            if entry.header is not None and frame.header != entry.header:
                return self._drop("gimbal_header_required")
            if entry.destination is not None and frame.dst != entry.destination:
                return self._drop("strict_destinations")
        self.sync()
        now = self._last
        if self._gap_s:
            if self._last_command is not None and now - self._last_command < self._gap_s:
                return self._drop("command_pacing")
            self._last_command = now
        if len(self.received) >= MAX_RECEIVED:
            del self.received[: MAX_RECEIVED // 2]
        self.received.append(frame)
        req = Request(peer, frame, now)
        reply = self._dispatch(entry, frame, req)
        out: list[Outgoing]
        if reply is None:
            out = []
        else:
            refused = isinstance(reply, Frame) and reply.ident == self._error_ident
            data = reply if isinstance(reply, bytes) else self.encode(reply)
            if entry is not None and entry.slow and not refused:
                self._answer_late(Outgoing(peer, data), now)
                out = []
            else:
                out = [Outgoing(peer, data)]
        if req.notes:
            out.extend(Outgoing(peer, self.encode(f)) for f in req.notes)
        return out

    def error_frame(self, request: Frame) -> Frame:
        key = (request.dst, request.src)
        frame = self._errors.get(key)
        if frame is None:
            frame = self._errors[key] = self.dialect.notification(
                self._error_ident, src=request.dst, dst=request.src, header="#TP", error="!!"
            )
        return frame

    def _dispatch(self, entry: Entry | None, frame: Frame, req: Request) -> Frame | bytes | None:
        d = self.dialect
        if entry is None or not entry.supported or frame.src not in d.host_addresses:
            return self.error_frame(frame)
        msg = d.decode(frame)
        if msg.fields is None or msg.form is None or msg.form.direction != REQUEST:
            return self.error_frame(frame)
        spec = entry.spec
        try:
            for name, lo, hi in entry.limits:
                value = msg.fields.get(name)
                if isinstance(value, (int, float)) and not isinstance(value, bool) and not lo <= value <= hi:
                    raise RefusedError(f"{name} {value} outside {lo:g}..{hi:g} on the {self.model.name}")
            if entry.ignored:
                return None  # the firmware drops it: no effect, no echo
            if entry.needs_video and frame.rw == "w" and not self.state.camera.video_output:
                return frame.swapped()  # acknowledged, but the camera does nothing yet
            if entry.signed and msg.fields:
                # Handlers work in the API convention; wire signs are applied here, once, both ways.
                msg = msg._replace(fields=flip(spec, msg.fields, self.signs))
            result = entry.handler(self.state, msg, req)
            if isinstance(result, Reply):
                if not result.send:
                    return None
                if result.values is None:
                    return frame.swapped()
                return self._answer(entry, frame, result.values, result.rw)
            if frame.rw == "r":
                if result is None:
                    raise RefusedError(f"{frame.ident} query has no answer")
                return self._answer(entry, frame, result)
            if entry.silent_motion:
                return None
            if result is not None and entry.echo_form:
                return self._answer(entry, frame, result)
            return frame.swapped()
        except (RefusedError, TopGimbalError, ValueError):
            req.notes.clear()
            return self.error_frame(frame)
        except Exception as exc:  # a handler bug must not take the simulator down
            self.errors += 1
            log.warning(
                "%s: %s raised %s: %s; answered with the error frame",
                self.model.name,
                frame.text(),
                type(exc).__name__,
                exc,
            )
            req.notes.clear()
            return self.error_frame(frame)

    def _answer(self, entry: Entry, request: Frame, values: dict[str, Any], rw: str | None = None) -> bytes:
        """The answer's bytes. Answers repeat (a gimbal at rest, a stored setting): the bytes for
        the same request and values are kept, so a repeated query costs no encoding."""
        try:
            key: Hashable = (request.ident, request.src, request.dst, rw or request.rw, *values.items())
            data = self._answers.get(key)
        except TypeError:  # an unhashable value: encode every time
            key, data = None, None
        if data is None:
            wire = flip(entry.spec, values, self.signs) if entry.signed else values
            data = self.encode(self.dialect.response(request, rw=rw, **wire))
            if key is not None:
                if len(self._answers) >= MAX_CACHED_ANSWERS:
                    self._answers.clear()
                self._answers[key] = data
        return data

    def _answer_late(self, out: Outgoing, now: float) -> None:
        delay = self.quirk_values.get("late_answers")
        if delay is None:
            self.dropped["late_answers"] = self.dropped.get("late_answers", 0) + 1
            return  # never answered
        self._late_seq += 1
        heapq.heappush(self._late, (now + delay, self._late_seq, out))

    def encode(self, frame: Frame) -> bytes:
        """Frame -> bytes with this model's output quirks."""
        if self._lowercase and frame.header == "#TP":
            frame = frame._replace(header="#tp")
        if self._ver_length and frame.rw == "r" and len(frame.data) == 6 and frame.ident in self._versions:
            frame = frame._replace(declared_length=3)
        data = frame.to_bytes()
        return data + b"\r\n" if self._crlf else data

    # -- streams and reports ---------------------------------------------------------------------

    def subscribed(self, peer: Hashable, ident: str) -> bool:
        return self.state.streams.subscribed(peer, ident)

    def forget(self, peer: Hashable) -> None:
        """A peer went away (TCP connection closed): drop its parser and subscriptions."""
        self._parsers.pop(peer, None)
        self.state.streams.forget(peer)

    def next_due(self) -> float | None:
        # Once a stream frame (a thousand times a frame period in a fleet): tests, no tuple.
        state = self.state
        t = state.streams.next_due()
        if state.camera.moving or state.gimbal.moving:
            motors = self._last + MOTOR_STEP_S
            if t is None or motors < t:
                t = motors
        coast = state.coast_until
        if coast is not None and (t is None or coast < t):
            t = coast
        if self._late:
            late = self._late[0][0]
            if t is None or late < t:
                t = late
        return t

    def tick(self, early_s: float = 0.0) -> list[Outgoing]:
        """Everything due up to now (stream frames up to `early_s` ahead), in time order, each
        sampled at its own due time. A real-time caller whose timers fire late by up to a
        millisecond (epoll rounds timeouts up to whole ms) wakes that much early and passes it
        here, so frames leave within [due - early_s, due] instead of up to 2 ms late."""
        now = self.clock.now()
        out: list[Outgoing] = []
        state = self.state
        streams = state.streams
        limit = now + early_s + 1e-9
        while (s := streams.pop_due(limit)) is not None:
            self.sync(s.next_due)
            try:
                frames = s.report(state, s)
                if frames is not s.last_frames:
                    s.last_frames, s.last_data = frames, [self.encode(f) for f in frames]
            except Exception as exc:  # a report that cannot be built ends its stream, not the device
                self.errors += 1
                what = f"{type(exc).__name__}: {exc}"
                log.warning("%s: the %s stream failed (%s) and was stopped", self.model.name, s.ident, what)
                streams.by_key.pop((s.peer, s.ident), None)
                continue
            for data in s.last_data:
                out.append(Outgoing(s.peer, data, reply=False))
            s.next_due += s.period
            if s.next_due < now - STREAM_CATCH_UP_S:
                # Fell far behind (a suspended process): resynchronise rather than burst. Shorter
                # stalls are caught up, so the mean rate stays what the host asked for.
                s.next_due = now
            if streams.alive(s):
                streams.push(s)
        self.sync(now)
        if state.camera.events:
            self._zoom_events(out)
        while self._late and self._late[0][0] <= now:
            out.append(heapq.heappop(self._late)[2])
        return out

    def _zoom_events(self, out: list[Outgoing]) -> None:
        stopped = "zoom_stopped" in self.state.camera.events
        self.state.camera.events.clear()
        if stopped and self.state.zoom_host is not None:
            peer, host = self.state.zoom_host
            frame = zoom_report(self.state, host)
            if frame is not None:
                out.append(Outgoing(peer, self.encode(frame), reply=False))

    # -- persistence -----------------------------------------------------------------------------

    def snapshot(self) -> dict[str, Any]:
        return self.state.snapshot()

    def restore(self, state: Mapping[str, Any]) -> None:
        self.state.restore(state)

    def factory_reset(self) -> None:
        self.state.factory_reset()


def _no_signs(model: DeviceModel) -> DeviceModel:
    """`model` with every value signed as its document says (the wire_signs quirk off)."""
    return replace(model, wire_signs={})


__all__ = ["TOPOTEK_STREAM_HZ", "Device", "Outgoing"]
