"""What a handler sees: the device's world as one small object (`SimState`), the request being
answered (`Request`), and how to answer (`Reply`, `RefusedError`).

A handler is `handler(state, msg, req) -> Result` where `msg` is the decoded request with fields in
user units and in the API sign convention (the device maps wire signs both ways). It changes the
state and returns what to answer:

- `None`: the echo (a write), the protocol's rule for control commands;
- a dict: field values for `dialect.response(request, **values)` (a query's answer), or for a
  write, the values of the form the profile's `echo_rules` names instead of the echo (TOPOTEK
  REC / CAP feedback with a file index); without such a rule a write is echoed;
- `Reply(...)`: values with another control character, or `Reply(send=False)` for no answer.

`RefusedError` means the device cannot do it (photo without a card): the error frame. Frames to
send after the reply (ZMP, LRF results) go to `req.notify`. Handlers never see the device's
machinery (parsers, quirk filters, encoding, traffic log): only this state.
"""

from __future__ import annotations

import random
from collections.abc import Callable, Hashable, Mapping
from dataclasses import dataclass, field
from datetime import datetime
from typing import Any, Union

from ..errors import TopGimbalError
from ..protocol import DeviceModel, Dialect, Frame, Message
from ..protocol.commands import factory_values, stored_form
from ..protocol.signs import flip
from .physics import GimbalPhysics
from .state import CameraState, HostFeed, NetworkState
from .streams import Key, ReportFn, Stream, Streams
from .targets import Target, TargetView, views
from .terrain import TerrainGround
from .tracker import CameraTracker, hfov_for

# Roles whose commands are reports, not settings a device stores.
NOT_STORED = frozenset({"error", "attitude", "earth_attitude"})


class RefusedError(TopGimbalError):
    """The device cannot do this: answer with the error frame."""


@dataclass(frozen=True)
class Reply:
    values: dict[str, Any] | None = None
    rw: str | None = None
    send: bool = True


@dataclass
class Request:
    """The request being handled: who sent it, the frame, the time, and frames to send after."""

    peer: Hashable
    frame: Frame
    now: float
    notes: list[Frame] = field(default_factory=list)

    @property
    def host(self) -> str:
        """The host's address letter (U or P): where replies and streams are addressed."""
        return self.frame.src

    def notify(self, frame: Frame) -> None:
        self.notes.append(frame)


Result = Union[None, dict[str, Any], Reply]  # noqa: UP007  (a runtime alias: py3.10 syntax limits)
Handler = Callable[["SimState", Message, Request], Result]


@dataclass(eq=False)
class SimState:
    """The device's world: model profile and dialect, quirk switches, gimbal physics, camera,
    network, the vehicle's position, stored settings (by identifier, user units), identity and
    the hosts' subscriptions. Built by `new_state`."""

    model: DeviceModel
    dialect: Dialect
    signs: Mapping[str, int]
    quirks: Mapping[str, bool]
    seed: int
    gimbal: GimbalPhysics
    camera: CameraState
    network: NetworkState = field(default_factory=NetworkState)
    position: HostFeed = field(default_factory=HostFeed)
    settings: dict[str, dict[str, Any]] = field(default_factory=dict)
    streams: Streams = field(default_factory=Streams)
    uid: int = 0
    serial: str = ""
    vehicle_input: bool = True  # whether vehicle attitude from the host counts (SkyDroid: after FAE)
    vehicle_heard: bool = False  # a vehicle attitude arrived (the heading may also come alone: sim/world.py)
    stream_hz: float | None = None  # rate of on / off streams (TOPOTEK GAA, GIA); None: the profile's
    dirty: bool = False  # persistent state changed
    reboots: int = 0
    zoom_host: tuple[Hashable, str] | None = None  # who moved the zoom last (ZMP goes there)
    coast_until: float | None = None  # when a stop that has not taken yet takes (stop_coasts quirk)
    coast_axes: tuple[str, ...] = ()  # the axes that stop then
    rng: random.Random = field(default_factory=random.Random)
    # Called on the simulator's thread as (event, file index) for "photo", "record_start" and
    # "record_stop" (the media store: video/media.py). A listener must not raise.
    capture_listeners: list[Callable[[str, int], None]] = field(default_factory=list)
    # The simulated world's targets (sim --target) and the camera's own tracker (sim/tracker.py).
    targets: tuple[Target, ...] = ()
    tracker: CameraTracker | None = None
    # The ground the laser measures (sim --terrain: a TerrainGround); None: flat ground at
    # altitude 0, the host's ALT being the height above it.
    terrain: TerrainGround | None = None

    def target_views(self, now: float) -> tuple[TargetView, ...]:
        """Every target at device time `now` (target paths count from power-on)."""
        return views(self.targets, now - self.camera.booted_at)

    def tracking_hfov_deg(self) -> float:
        """The visible picture's horizontal field of view now (what the tracker works in)."""
        return hfov_for(self.model, self.camera.zoom_x)

    def start_tracking(self, now: float, box: tuple[float, float, float, float]) -> None:
        """The camera's tracker locks on what is in `box` (centre x, y, width, height, fractions)."""
        assert self.tracker is not None
        self.tracker.start(now, self.gimbal, self.tracking_hfov_deg(), box, self.target_views(now))
        self.camera.tracking = self.tracker.state

    def set_tracking(self, state: str) -> None:
        """Arm the tracker (state "waiting") or stop it."""
        assert self.tracker is not None
        if state == "waiting":
            self.tracker.arm(self.gimbal)
        else:
            self.tracker.stop(self.gimbal)
        self.camera.tracking = self.tracker.state

    def report(self, ident: str, *, dst: str, src: str | None = None, rw: str | None = None, **values: Any) -> Frame:
        """An unsolicited frame from API-convention values (wire signs applied here)."""
        spec = self.dialect.command(ident)
        if spec.wire_sign_fields:
            values = flip(spec, values, self.signs)
        return self.dialect.notification(ident, src=src or spec.address, dst=dst, rw=rw, **values)

    def subscribe(self, req: Request, ident: str, rate_hz: float, report: ReportFn) -> None:
        self.streams.subscribe(req.peer, ident, req.host, rate_hz, req.now, report)

    def stream_rate(self, ident: str, asked_hz: float | None) -> float:
        """The rate a stream switched on by `ident` runs at: what the host asked (`asked_hz`; None
        for an on / off switch), unless the profile fixes it (the fixed_stream_rate quirk)."""
        fixed = self.model.stream_rates_hz.get(ident)
        if asked_hz is None:
            return self.stream_hz or fixed or DEFAULT_STREAM_HZ
        if asked_hz > 0 and fixed and self.quirks.get("fixed_stream_rate"):
            return fixed
        return asked_hz

    def identity(self, role: str, address: str | None = None) -> str | None:
        """What the device reports for an identity role; `role@ADDRESS` entries of the profile
        answer for one address (SIP: the lens answers its own version)."""
        ident = self.model.identity
        return ident.get(f"{role}@{address}") or ident.get(role)

    def factory_settings(self) -> dict[str, dict[str, Any]]:
        """Factory values of every stored setting the model has, from the catalog."""
        out: dict[str, dict[str, Any]] = {}
        for spec in self.dialect.supported(self.model):
            if spec.role not in NOT_STORED and stored_form(spec) is not None:
                out[spec.ident] = factory_values(spec)
        uid = self.dialect.by_role("uid", self.model)
        if uid is not None and uid.ident in out:
            out[uid.ident]["uid"] = self.uid
        return out

    def factory_reset(self) -> None:
        self.network = NetworkState()
        self.uid = first_uid(self.seed)
        self.settings = self.factory_settings()
        self.gimbal.mode, self.gimbal.mount = "follow", "hanging"
        self.gimbal.trims = {"x": 0.0, "y": 0.0, "z": 0.0}
        self.dirty = True

    # -- persistence (the state file's "state" object) ---------------------------------------------

    def snapshot(self) -> dict[str, Any]:
        g = self.gimbal
        return {
            "model": self.model.name,
            "network": self.network.snapshot(),
            "uid": self.uid,
            "settings": {
                ident: {k: _jsonable(v) for k, v in values.items()} for ident, values in self.settings.items()
            },
            "camera": self.camera.snapshot(),
            "gimbal": {"mode": g.mode, "mount": g.mount, "trims": dict(g.trims)},
        }

    def restore(self, saved: Mapping[str, Any]) -> None:
        self.network.restore(saved.get("network") or {})
        if isinstance(saved.get("uid"), int):
            self.uid = saved["uid"]
        for ident, values in (saved.get("settings") or {}).items():
            if ident in self.settings and isinstance(values, dict):
                store = self.settings[ident]
                store.update({k: _restored(store[k], v) for k, v in values.items() if k in store})
        self.camera.restore(saved.get("camera") or {})
        g = saved.get("gimbal") or {}
        if g.get("mode") in ("follow", "lock"):
            self.gimbal.mode = g["mode"]
        if g.get("mount") in ("hanging", "inverted"):
            self.gimbal.mount = g["mount"]
        if isinstance(g.get("trims"), dict):
            self.gimbal.trims.update({k: float(v) for k, v in g["trims"].items() if k in self.gimbal.trims})


def _jsonable(value: object) -> object:
    """A stored setting as the state file holds it: a time (TIM) as ISO 8601 text."""
    return value.isoformat() if isinstance(value, datetime) else value


def _restored(current: object, saved: object) -> object:
    """A saved setting back in the type the device keeps (a time from its ISO text); text that is
    not a time leaves the factory value."""
    if isinstance(current, datetime):
        try:
            return datetime.fromisoformat(saved) if isinstance(saved, str) else current
        except ValueError:
            return current
    return saved


class StateView:
    """The device's state as the simulator, the video package and tests read it (`sim.gimbal`,
    `sim.camera`, `sim.settings`...): attributes of its `SimState`."""

    state: SimState

    @property
    def gimbal(self) -> GimbalPhysics:
        return self.state.gimbal

    @property
    def camera(self) -> CameraState:
        return self.state.camera

    @property
    def position(self) -> HostFeed:
        return self.state.position

    @property
    def network(self) -> NetworkState:
        return self.state.network

    @property
    def uid(self) -> int:
        return self.state.uid

    @property
    def serial(self) -> str:
        return self.state.serial

    @property
    def reboots(self) -> int:
        return self.state.reboots

    @property
    def settings(self) -> dict[str, dict[str, Any]]:
        return self.state.settings

    @property
    def streams(self) -> dict[Key, Stream]:
        """Subscriptions by (peer, identifier)."""
        return self.state.streams.by_key

    @property
    def dirty(self) -> bool:
        return self.state.dirty

    @dirty.setter
    def dirty(self, value: bool) -> None:
        self.state.dirty = value


DEFAULT_STREAM_HZ = 10.0  # an on / off stream whose rate neither the profile nor the host gives


def first_uid(seed: int) -> int:
    return random.Random(seed).getrandbits(32)


def serial_for(model: DeviceModel, seed: int) -> str:
    """The profile's serial number with its trailing digits replaced by the seed (seed 0: as the
    profile says), so every simulated camera of a fleet has its own."""
    base = model.identity.get("serial_number") or f"{model.name[:3].upper()}00000000000"
    digits = len(base) - len(base.rstrip("0123456789"))
    if not seed or not digits:
        return base
    return base[: len(base) - digits] + f"{seed % 10**digits:0{digits}d}"


def new_state(
    model: DeviceModel,
    dialect: Dialect,
    *,
    signs: Mapping[str, int],
    quirks: Mapping[str, bool],
    seed: int = 0,
    stream_hz: float | None = None,
) -> SimState:
    """A device fresh from the factory."""
    m = model
    gimbal = GimbalPhysics.for_limits(
        m.yaw_range_deg, m.pitch_range_deg, m.roll_range_deg, m.max_rate_deg_s, m.max_accel_deg_s2
    )
    camera = CameraState(m)
    state = SimState(m, dialect, signs, quirks, seed, gimbal, camera, stream_hz=stream_hz)
    state.tracker = CameraTracker.for_model(m)
    state.uid = first_uid(seed)
    state.serial = serial_for(m, seed)
    state.rng = random.Random(f"{seed}/device")
    state.settings = state.factory_settings()
    # Vehicle attitude counts from the start unless the model has a switch for it (SkyDroid FAE).
    state.vehicle_input = dialect.by_role("vehicle_attitude_enable", m) is None
    vom = dialect.by_role("video_output", m)
    if vom is not None:
        state.camera.video_output = state.settings.get(vom.ident, {}).get("output") == "on"
    return state


__all__ = [
    "DEFAULT_STREAM_HZ",
    "Handler",
    "RefusedError",
    "Reply",
    "Request",
    "Result",
    "SimState",
    "StateView",
    "new_state",
    "serial_for",
]
