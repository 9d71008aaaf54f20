"""The sans-I/O virtual camera: bytes in, bytes out, time from a clock.

`Device.receive(peer, data)` takes what a host sent (one datagram, or a chunk of a byte stream)
and returns the frames to send back, each addressed to a peer. `Device.tick()` returns what is due
on its own (attitude streams, ZMP after a zoom, rangefinder results). Peers are opaque hashable
objects owned by the servers; the device only uses them as addresses and subscription keys.

Rules (both documents, §2.3): a control command is echoed with swapped addresses; a query is
answered with data; an unknown identifier, malformed data, or a command the model does not
support gets the error frame; a frame with a bad checksum is ignored.
"""

from __future__ import annotations

import random
from collections.abc import Hashable, Mapping
from dataclasses import dataclass, field
from typing import Any

from ..errors import CatalogError, TopGimbalError
from ..protocol import Diagnostic, Frame, FrameParser, Message, get_model, make_frame
from ..protocol.catalog import RESPONSE
from ..protocol.frame import DEVICE_ADDRESSES
from ..protocol.signs import flip, resolve_signs
from . import handlers as _handlers
from . import quirks as quirk_table
from .clock import Clock, MonotonicClock
from .dispatch import DEFAULTS, HANDLERS, Ctx, Refuse, Reply, default_value
from .physics import Gimbal
from .state import CameraState, NetworkState

# TOPOTEK's GAA / GIA switch a stream on without a rate; this is the simulator's (documented) rate.
TOPOTEK_STREAM_HZ = 10.0
MAX_RECEIVED = 10000
STREAM_CATCH_UP_S = 1.0


@dataclass
class Outgoing:
    peer: Hashable
    data: bytes
    reply: bool = True  # an answer to a request (late-reply faults apply), not a stream frame


@dataclass
class Stream:
    """One host's subscription to a periodic report."""

    peer: Hashable
    ident: str  # identifier of the frames sent (GAC, GIA, LRF, TMP)
    host: str  # address letter of the host (U or P)
    period: float
    next_due: float


@dataclass
class Position:
    """What the host tells the camera about the vehicle (LAT/LON/ALT/AZI/GPS)."""

    lat_deg: float | None = None
    lon_deg: float | None = None
    alt_m: float | None = None
    azimuth_deg: float | None = None
    speed_m_s: float = 0.0


@dataclass
class Device:
    model_name: str
    seed: int = 0
    clock: Clock = field(default_factory=MonotonicClock)
    quirk_overrides: Mapping[str, bool] | None = None
    topotek_stream_hz: float = TOPOTEK_STREAM_HZ

    def __post_init__(self) -> None:
        self.dialect, self.model = get_model(self.model_name)
        self.model_name = self.model.name
        self.quirks = quirk_table.resolve(self.model.name, self.quirk_overrides)
        self.rng = random.Random(self.seed)
        m = self.model
        self.signs = resolve_signs(m)
        self.gimbal = Gimbal.for_limits(
            m.yaw_range_deg, m.pitch_range_deg, m.roll_range_deg, m.max_rate_deg_s, m.max_accel_deg_s2
        )
        self.camera = CameraState(optical_zoom_max=m.optical_zoom_max, digital_zoom_max=m.digital_zoom_max)
        self.network = NetworkState()
        self.uid = self.rng.getrandbits(32)
        self.serial = f"{m.name[:3].upper()}{self.rng.randrange(10**11):011d}"[:14]
        self.settings = self.default_settings()
        self.position = Position()
        self.vehicle_input = self.dialect.name == "topotek"  # SkyDroid: FAE switches FAI on
        self.streams: dict[tuple[Hashable, str], Stream] = {}
        self.received: list[Frame] = []
        self.dirty = False
        self.reboots = 0
        self._parsers: dict[Hashable, FrameParser] = {}
        self._last = self.clock.now()
        self._zoom_peer: tuple[Hashable, str] | None = None
        self._extra: list[tuple[Frame, Hashable]] = []

    # -- settings --------------------------------------------------------------------------------

    def default_settings(self) -> dict[str, dict[str, Any]]:
        """Factory values of every stored setting the model has, from the catalog's read forms."""
        out: dict[str, dict[str, Any]] = {}
        for spec in self.dialect.supported(self.model):
            forms = spec.forms_for("r", RESPONSE) or spec.forms_for("w", "request")
            if not forms or spec.ident in ("GAC", "GIC", "ERE"):
                continue
            values = {f.name: default_value(f.codec) for f in forms[0].fields}
            values.update({k: v for k, v in DEFAULTS.get(spec.ident, {}).items() if k in values or not forms[0].fields})
            out[spec.ident] = values
        if "UID" in out:
            out["UID"]["uid"] = self.uid
        return out

    def report(self, ident: str, *, src: str, dst: str, rw: str | None = None, **values: Any) -> Frame:
        """An unsolicited frame from API-convention values (wire signs applied here)."""
        spec = self.dialect.command(ident)
        return self.dialect.notification(ident, src=src, dst=dst, rw=rw, **flip(spec, values, self.signs))

    # -- time ------------------------------------------------------------------------------------

    def sync(self, t: float | None = None) -> None:
        """Bring physics and motors up to time `t` (never backwards)."""
        t = self.clock.now() if t is None else t
        dt = t - self._last
        if dt > 0:
            self.gimbal.advance(dt)
            self.camera.advance(dt)
            self._last = t

    @property
    def now(self) -> float:
        return self._last

    # -- input -----------------------------------------------------------------------------------

    def receive(self, peer: Hashable, data: bytes, *, datagram: bool = True) -> list[Outgoing]:
        """Handle what `peer` sent. A datagram is complete in itself (leftover bytes are dropped);
        a stream chunk may end mid-frame (the rest waits for the next chunk)."""
        parser = self._parsers.get(peer)
        if parser is None:
            parser = self._parsers[peer] = FrameParser(max_data_length=0xFF)
        # A datagram's end is a frame boundary: nothing is kept for the next one.
        items = parser.feed_datagram(data) if datagram else parser.feed(data)
        out: list[Outgoing] = []
        for item in items:
            if isinstance(item, Diagnostic):
                continue  # bad checksum / garbage: ignored, as a device does
            out.extend(self.handle(peer, item))
        return out

    def handle(self, peer: Hashable, frame: Frame) -> list[Outgoing]:
        if frame.dst not in DEVICE_ADDRESSES or frame.src in DEVICE_ADDRESSES:
            return []  # not addressed to a device (a reply looping back): nothing to do
        self.sync()
        if len(self.received) >= MAX_RECEIVED:
            del self.received[: MAX_RECEIVED // 2]
        self.received.append(frame)
        ctx = Ctx(peer, frame, self.now)
        reply = self._dispatch(frame, ctx)
        out = [] if reply is None else [Outgoing(peer, self.encode(reply))]
        out.extend(Outgoing(peer, self.encode(f)) for f in ctx.notes)
        return out

    def error_frame(self, request: Frame) -> Frame:
        return make_frame("ERE", b"!!", src=request.dst, dst=request.src, header="#TP")

    def _dispatch(self, frame: Frame, ctx: Ctx) -> Frame | None:
        d = self.dialect
        if frame.src not in d.host_addresses:
            return self.error_frame(frame)
        if not d.supports(self.model, frame.ident) or frame.ident == "ERE":
            return self.error_frame(frame)
        msg = d.decode(frame)
        if msg.fields is None or msg.form is None or msg.spec is None or msg.form.direction != "request":
            return self.error_frame(frame)
        spec = msg.spec
        try:
            d.check_values(self.model, frame.ident, msg.fields)
            # Handlers work in the API convention; wire signs are applied here, once, both ways.
            msg = msg._replace(fields=flip(spec, msg.fields, self.signs))
            handler = HANDLERS.get(frame.ident, _generic)
            result = handler(self, msg, ctx)
            if isinstance(result, Reply):
                if not result.send:
                    return None
                if result.values is None:
                    return self._echo(frame)
                return d.response(frame, rw=result.rw, **flip(spec, result.values, self.signs))
            if result is None:
                if frame.rw == "r":
                    raise Refuse(f"{frame.ident} query has no answer")
                if self.quirks["no_motion_echo"] and spec.motion:
                    return None
                return self._echo(frame)
            return d.response(frame, **flip(spec, result, self.signs))
        except (Refuse, CatalogError, TopGimbalError, ValueError):
            ctx.notes.clear()
            return self.error_frame(frame)

    def _echo(self, frame: Frame) -> Frame:
        return frame.swapped()

    def encode(self, frame: Frame) -> bytes:
        """Frame -> bytes with this model's output quirks."""
        if self.quirks["lowercase_header"] and frame.header == "#TP":
            frame = frame._replace(header="#tp")
        if self.quirks["ver_wrong_length"] and frame.ident == "VER" and frame.rw == "r" and len(frame.data) == 6:
            frame = frame._replace(declared_length=3)
        data = frame.to_bytes()
        return data + b"\r\n" if self.quirks["crlf"] else data

    # -- streams ---------------------------------------------------------------------------------

    def subscribe(self, ctx: Ctx, ident: str, rate_hz: float) -> None:
        key = (ctx.peer, ident)
        if rate_hz <= 0:
            self.streams.pop(key, None)
            return
        period = 1.0 / rate_hz
        old = self.streams.get(key)
        first = ctx.now + period if old is None else min(old.next_due, ctx.now + period)
        self.streams[key] = Stream(ctx.peer, ident, ctx.host, period, first)

    def subscribed(self, peer: Hashable, ident: str) -> bool:
        return (peer, ident) in self.streams

    def forget(self, peer: Hashable) -> None:
        """A peer went away (TCP connection closed): drop its parser and subscriptions."""
        self._parsers.pop(peer, None)
        for key in [k for k in self.streams if k[0] == peer]:
            del self.streams[key]

    def next_due(self) -> float | None:
        times = [s.next_due for s in self.streams.values()]
        if self.camera.moving or self.gimbal.moving:
            times.append(self._last + 0.05)  # keep motors integrating so ZMP goes out on time
        return min(times) if times else None

    def tick(self, early_s: float = 0.0) -> list[Outgoing]:
        """Everything due up to now (stream frames up to `early_s` ahead), in time order, each
        sampled at its own due time. A real-time caller whose timers fire late by up to a
        millisecond (epoll rounds timeouts up to whole ms) wakes that much early and passes it
        here, so frames leave within [due - early_s, due] instead of up to 2 ms late."""
        now = self.clock.now()
        out: list[Outgoing] = []
        while True:
            due = [s for s in self.streams.values() if s.next_due <= now + early_s + 1e-9]
            if not due:
                break
            s = min(due, key=lambda s: s.next_due)
            self.sync(s.next_due)
            frame = _handlers.stream_frame(self, s)
            if frame is not None:
                out.append(Outgoing(s.peer, self.encode(frame), reply=False))
            s.next_due += s.period
            if s.next_due < now - STREAM_CATCH_UP_S:
                # Fell far behind (a suspended process): resynchronise rather than burst. Shorter
                # stalls are caught up, so the mean rate stays what the host asked for.
                s.next_due = now
            if (s.peer, s.ident) not in self.streams:
                continue
        self.sync(now)
        for frame, peer in _handlers.pending_reports(self):
            out.append(Outgoing(peer, self.encode(frame), reply=False))
        return out

    # -- persistence -----------------------------------------------------------------------------

    def snapshot(self) -> dict[str, Any]:
        g = self.gimbal
        return {
            "model": self.model.name,
            "network": self.network.snapshot(),
            "uid": self.uid,
            "settings": self.settings,
            "camera": self.camera.snapshot(),
            "gimbal": {"mode": g.mode, "mount": g.mount, "trims": dict(g.trims)},
        }

    def restore(self, state: Mapping[str, Any]) -> None:
        self.network.restore(state.get("network") or {})
        if isinstance(state.get("uid"), int):
            self.uid = state["uid"]
        for ident, values in (state.get("settings") or {}).items():
            if ident in self.settings and isinstance(values, dict):
                self.settings[ident].update({k: v for k, v in values.items() if k in self.settings[ident]})
        self.camera.restore(state.get("camera") or {})
        g = state.get("gimbal") or {}
        if g.get("mode") in ("follow", "lock"):
            self.gimbal.mode = g["mode"]
        if g.get("mount") in ("hanging", "inverted"):
            self.gimbal.mount = g["mount"]
        if isinstance(g.get("trims"), dict):
            self.gimbal.trims.update({k: float(v) for k, v in g["trims"].items() if k in self.gimbal.trims})

    def factory_reset(self) -> None:
        uid_rng = random.Random(self.seed)
        self.network = NetworkState()
        self.uid = uid_rng.getrandbits(32)
        self.settings = self.default_settings()
        self.gimbal.mode, self.gimbal.mount = "follow", "hanging"
        self.gimbal.trims = {"x": 0.0, "y": 0.0, "z": 0.0}
        self.dirty = True


def _generic(dev: Device, msg: Message, ctx: Ctx) -> Any:
    return _handlers.setting(dev, msg, ctx)
