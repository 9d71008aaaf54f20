"""What a host keeps sending because the model's profile says so (`host_feeds`: {ident: Hz}), and
the frames it sends once before (`host_setup`).

Which values a feed carries comes from its command's catalog role:
- `time` / `utc_time` (TIM, UTC): the camera's clock. From the host's UTC clock, or from the time the
  program gave (`feed(time_utc=...)`, e.g. the autopilot's GPS time) moved on by the monotonic
  clock since. A camera without a clock (quirk `no_clock`, C11) gets it from the moment the client
  connects; any other model only once a time was given (the machine's clock may be wrong: a
  camera with its own clock is better left alone than set from it). A frame that carries whole
  seconds (TOPOTEK UTC) is sent as a second of the fed time starts, carrying that second: cut from
  any moment, the camera's clock ran up to a second behind (issue 35.5).
- `latitude` / `longitude` / `altitude` / `azimuth` (LAT, LON, ALT, AZI) and `vehicle_position`
  (TOPOTEK GPS): the last position fix given (`feed(lat_deg=..., ...)`). No fix, no feed: a fix
  older than `FIX_MAX_AGE_S` is not sent (stale), `feed(fix=False)` stops these feeds, and a zero
  position is never invented.
- `vehicle_attitude` (FAI, UAV): the last values given (`cam.vehicle_attitude(...)`).

Feeds of one rate go out together, in the profile's order (TOPOTEK: LAT, LON, ALT, AZI every
100 ms, as ArduPilot's AP_Mount_Topotek sends them). A setup frame whose role is `<role>_enable`
goes out just before the feed of `<role>` starts, any other setup frame right after connecting.
Feeds are sent without waiting for an echo (the next one follows anyway); a feed that fails is
logged and retried at its next period. `connect(..., host_feeds=False)` turns all this off.
Once the model check says the device is another model (`halt()`), the periodic feeds stop (their
frames are the wrong model's); what they would carry is still kept, and they start again if the
verdict is corrected.

This module needs only `FeedTarget` of the client core (no import of core.py).
"""

from __future__ import annotations

import asyncio
import datetime
import logging
import math
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Protocol

from ..clock import monotonic, wall_time
from ..errors import TopGimbalError, UnsupportedError
from ..geo.earth import wrap360
from ..protocol import CommandSpec, DeviceModel, Dialect, Frame

log = logging.getLogger("topgimbal.client")

# Feeds the client can fill by itself, by catalog role.
CLOCK_ROLES = frozenset({"time", "utc_time"})
WHOLE_SECOND_SLACK_S = 0.02  # a whole-seconds clock frame sent this late in its second still counts as on time
VEHICLE_ROLE = "vehicle_attitude"
POSITION_ROLES = frozenset({"latitude", "longitude", "altitude", "azimuth", "vehicle_position"})
FIX_MAX_AGE_S = 2.0  # a position older than this is stale: not sent


class FeedOptions(Protocol):
    @property
    def host_feeds(self) -> bool: ...


class FeedTarget(Protocol):
    """What the feeds need of a client."""

    @property
    def dialect(self) -> Dialect: ...
    @property
    def model(self) -> DeviceModel: ...
    @property
    def options(self) -> FeedOptions: ...
    @property
    def url(self) -> str: ...
    @property
    def connected(self) -> bool: ...
    def build_from(self, ident: str, values: Mapping[str, object]) -> Frame: ...
    def send_nowait(self, frame: Frame, *, background: bool = False) -> None: ...
    async def send_request(self, frame: Frame) -> object: ...


@dataclass(frozen=True)
class FedPosition:
    """Where the user says the vehicle is, fed to the camera (`feed_position`): WGS84 degrees,
    altitude above mean sea level, heading true. (By role: `geo.Fix` is a located ground point,
    `autopilot.vehicle.VehicleFix` what the autopilot says.)"""

    lat_deg: float
    lon_deg: float
    alt_m: float
    heading_deg: float | None = None

    def __post_init__(self) -> None:
        for name, v, lim in (("lat_deg", self.lat_deg, 90.0), ("lon_deg", self.lon_deg, 180.0)):
            if not (isinstance(v, (int, float)) and math.isfinite(v) and -lim <= v <= lim):
                raise ValueError(f"{name} must be a number in -{lim:g}..{lim:g} (got {v!r})")
        if not (isinstance(self.alt_m, (int, float)) and math.isfinite(self.alt_m)):
            raise ValueError(f"alt_m must be a finite number (got {self.alt_m!r})")
        if self.heading_deg is not None and not math.isfinite(self.heading_deg):
            raise ValueError(f"heading_deg must be a finite number or None (got {self.heading_deg!r})")


Fix = FedPosition  # the name it had (issue 44: one class named Fix, geo.Fix)


class HostFeeds:
    def __init__(self, core: FeedTarget) -> None:
        self.core = core
        self.enabled = core.options.host_feeds
        self.tasks: dict[float, asyncio.Task[None]] = {}  # one task per rate (Hz)
        self.active: set[str] = set()  # idents being fed
        self.values: dict[str, dict[str, object]] = {}  # ident -> what its feed carries now
        self.sent: dict[str, int] = {}  # frames sent per feed
        self.fix: FedPosition | None = None
        self.fix_at: float | None = None  # monotonic time of the fix
        self.utc_offset_s: float | None = None  # given UTC minus monotonic; None: the host clock
        self.time_source = "host clock"
        self._setup_done: set[str] = set()
        self._resolution: dict[str, bool] = {}  # clock feed ident -> carries whole seconds only
        self.source_task: asyncio.Task[None] | None = None  # `feed_from`'s poll
        self.halted = False  # the device is another model: no feed is sent (module docstring)

    def _spec(self, ident: str) -> CommandSpec | None:
        core = self.core
        return core.dialect.commands.get(ident) if core.dialect.supports(core.model, ident) else None

    def feeds(self) -> dict[str, float]:
        """{ident: Hz} of the model's feeds that this dialect has."""
        return {i: hz for i, hz in self.core.model.host_feeds.items() if self._spec(i) is not None and hz > 0}

    def _idents(self, roles: frozenset[str]) -> list[str]:
        return [i for i in self.feeds() if (s := self._spec(i)) is not None and s.role in roles]

    async def start(self) -> None:
        """After connecting: the setup frames no feed waits for, then (camera without a clock) the
        clock feeds."""
        if not self.enabled:
            return
        feed_roles = {s.role for i in self.feeds() if (s := self._spec(i)) is not None}
        for ident, values in self.core.model.host_setup:
            spec = self._spec(ident)
            if spec is not None and spec.role.removesuffix("_enable") not in feed_roles:
                await self._setup(ident, values)
        if self.core.model.quirks.get("no_clock"):
            self._activate(self._idents(CLOCK_ROLES))

    async def vehicle_attitude(self, values: Mapping[str, object]) -> None:
        """New vehicle attitude values: fed at the profile's rate where it names a feed (after
        its setup frames), else sent once and acknowledged."""
        core = self.core
        spec = core.dialect.by_role(VEHICLE_ROLE, core.model)
        if spec is None:
            raise UnsupportedError(f"the {core.model.name} takes no vehicle attitude")
        core.build_from(spec.ident, values)  # checked before anything changes
        if not self.enabled or spec.ident not in self.feeds():
            await core.send_request(core.build_from(spec.ident, values))
            return
        await self._setup_for(spec)
        self.values[spec.ident] = dict(values)
        self._activate([spec.ident])

    def position(self, fix: FedPosition | None) -> list[str]:
        """A new position fix (None: no fix, the position feeds stop). Returns the idents fed."""
        if fix is None:
            self.fix = self.fix_at = None
            self.active -= set(self._idents(POSITION_ROLES))
            return []
        self.fix, self.fix_at = fix, monotonic()
        idents = self._idents(POSITION_ROLES)
        if self.enabled:
            self._activate(idents)
        return idents

    def set_time(self, utc: datetime.datetime, source: str = "given") -> list[str]:
        """The UTC time now (e.g. the autopilot's): the clock feeds carry it from now on."""
        if utc.tzinfo is None:
            raise ValueError("time_utc must be timezone-aware (UTC)")
        self.utc_offset_s = utc.timestamp() - monotonic()
        self.time_source = source
        idents = self._idents(CLOCK_ROLES)
        if self.enabled:
            self._activate(idents)
        return idents

    def active_position_feeds(self) -> list[str]:
        """The position feeds being sent now (LAT, LON, ALT...), in the profile's order."""
        return [i for i in self._idents(POSITION_ROLES) if i in self.active]

    def send_now(self, roles: frozenset[str] = POSITION_ROLES) -> int:
        """Send the active feeds of these roles once, now, outside their period: a fresh position
        right before a photo, so the camera's own tag is not up to a feed period old (the C12's
        LAT/LON go at 2 Hz: 5 m at 10 m/s). Paced like every frame. The number of frames queued."""
        n = 0
        for ident in self._idents(roles):
            spec = self._spec(ident)
            if ident not in self.active or spec is None or not self.core.connected or self.halted:
                continue
            values = self._current(ident, spec)
            if values is None:
                continue
            try:
                self.core.send_nowait(self.core.build_from(ident, values))
            except TopGimbalError as exc:
                log.info("%s: %s feed not sent: %s", self.core.url, ident, exc)
                continue
            self.sent[ident] = self.sent.get(ident, 0) + 1
            n += 1
        return n

    def utc_now(self) -> datetime.datetime:
        if self.utc_offset_s is None:
            return datetime.datetime.fromtimestamp(wall_time(), datetime.timezone.utc)
        return datetime.datetime.fromtimestamp(monotonic() + self.utc_offset_s, datetime.timezone.utc)

    def fix_fresh(self) -> bool:
        return self.fix is not None and self.fix_at is not None and monotonic() - self.fix_at <= FIX_MAX_AGE_S

    def status(self) -> dict[str, object]:
        """What is being fed now: {ident: {"hz", "sent", "what"}} plus the fix and time source."""
        feeds = self.feeds()
        out: dict[str, object] = {}
        for ident in sorted(self.active, key=list(feeds).index):
            spec = self._spec(ident)
            role = spec.role if spec is not None else "?"
            state = "sending"
            if self.halted:
                state = "stopped: the device is another model"
            elif role in POSITION_ROLES and not self.fix_fresh():
                state = "paused: no fresh fix"
            out[ident] = {"hz": feeds[ident], "sent": self.sent.get(ident, 0), "role": role, "state": state}
        fix = self.fix
        return {
            "enabled": self.enabled,
            "feeds": out,
            "fix": None if fix is None else {**fix.__dict__, "age_s": round(monotonic() - (self.fix_at or 0.0), 2)},
            "time_source": self.time_source
            if self.utc_offset_s is not None or self.active & set(self._idents(CLOCK_ROLES))
            else None,
        }

    def summary(self) -> str:
        """One line for `info` and the console: "LAT 10 Hz (sending), UTC 1 Hz (sending)"."""
        parts = []
        for ident, v in self.status()["feeds"].items():  # type: ignore[attr-defined]
            parts.append(f"{ident} {v['hz']:g} Hz ({v['state']})")
        return ", ".join(parts) or "nothing"

    def halt(self, on: bool) -> None:
        """The device is (`on`) or is no longer another model: stop the periodic feeds, or start
        the active ones again."""
        if on == self.halted:
            return
        self.halted = on
        if on:
            self._cancel_tasks()
        else:
            self._activate(sorted(self.active, key=list(self.feeds()).index))

    def stop(self) -> None:
        self._cancel_tasks()
        if self.source_task is not None:
            self.source_task.cancel()
            self.source_task = None

    def _cancel_tasks(self) -> None:
        for task in self.tasks.values():
            task.cancel()
        self.tasks.clear()

    # -- internals -------------------------------------------------------------------------------

    async def _setup_for(self, spec: CommandSpec) -> None:
        for ident, setup in self.core.model.host_setup:
            s = self._spec(ident)
            if s is not None and s.role == f"{spec.role}_enable":
                await self._setup(ident, setup)

    async def _setup(self, ident: str, values: Mapping[str, object]) -> None:
        if ident in self._setup_done or self.halted:
            return  # (halted: sent when the feeds start again, if they do)
        await self.core.send_request(self.core.build_from(ident, values))
        self._setup_done.add(ident)

    def _activate(self, idents: list[str]) -> None:
        feeds = self.feeds()
        for ident in idents:
            self.active.add(ident)
            hz = feeds[ident]
            if self.halted:
                continue  # kept for when the verdict is corrected; nothing sent meanwhile
            task = self.tasks.get(hz)
            if task is None or task.done():
                self.tasks[hz] = asyncio.ensure_future(self._run(hz))

    def _current(self, ident: str, spec: CommandSpec) -> dict[str, object] | None:
        role = spec.role
        if role in CLOCK_ROLES:
            name = spec.forms_for("w", "request")[0].fields[0].name
            now = self.utc_now()
            if self._whole_seconds(ident):
                now = (now + datetime.timedelta(microseconds=500_000)).replace(microsecond=0)
            return {name: now}
        if role in POSITION_ROLES:
            return self._position_values(role) if self.fix_fresh() else None
        return self.values.get(ident)

    def _to_whole_second(self, hz: float) -> float:
        """Seconds until the next whole second of the fed time when the feeds of rate `hz` include a
        clock frame that carries whole seconds only (0: send now)."""
        clocks = [i for i, r in self.feeds().items() if r == hz and i in self.active and self._is_clock(i)]
        if not any(self._whole_seconds(i) for i in clocks):
            return 0.0
        frac = self.utc_now().microsecond / 1e6
        return 0.0 if frac < WHOLE_SECOND_SLACK_S else 1.0 - frac

    def _is_clock(self, ident: str) -> bool:
        spec = self._spec(ident)
        return spec is not None and spec.role in CLOCK_ROLES

    def _whole_seconds(self, ident: str) -> bool:
        """Whether `ident`'s frame drops the fraction of a second (found once by encoding a time)."""
        known = self._resolution.get(ident)
        if known is None:
            probe = datetime.datetime(2000, 1, 1, 0, 0, 0, 600_000, tzinfo=datetime.timezone.utc)
            try:
                spec = self.core.dialect.command(ident)
                name = spec.forms_for("w", "request")[0].fields[0].name
                back = self.core.dialect.decode(self.core.build_from(ident, {name: probe})).fields or {}
                t = back.get(name)
                known = isinstance(t, datetime.datetime) and t.microsecond == 0
            except Exception:  # a form that cannot carry the probe: send the time as it is
                known = False
            self._resolution[ident] = known
        return known

    def _position_values(self, role: str) -> dict[str, object] | None:
        fix = self.fix
        assert fix is not None
        heading = None if fix.heading_deg is None else wrap360(fix.heading_deg)
        if role == "latitude":
            return {"lat_deg": fix.lat_deg}
        if role == "longitude":
            return {"lon_deg": fix.lon_deg}
        if role == "altitude":
            return {"alt_m": fix.alt_m}
        if role == "azimuth":
            return None if heading is None else {"azimuth_deg": min(heading, 359.9)}
        return {"heading_deg": heading or 0.0, "lat_deg": fix.lat_deg, "lon_deg": fix.lon_deg, "alt_m": fix.alt_m}

    async def _run(self, hz: float) -> None:
        """Every feed of rate `hz`, in the profile's order, once per period."""
        period_s = 1.0 / hz
        next_at = monotonic()
        while True:
            wait_s = self._to_whole_second(hz)
            if wait_s > 0:  # a whole-seconds clock frame goes out as its second starts (module docstring)
                await asyncio.sleep(wait_s)
                next_at = monotonic()
            for ident, rate in self.feeds().items():
                if rate != hz or ident not in self.active:
                    continue
                spec = self._spec(ident)
                values = None if spec is None else self._current(ident, spec)
                if values is not None and self.core.connected:
                    try:
                        # periodic: a photo or a command waiting for its turn goes first (Pacer)
                        self.core.send_nowait(self.core.build_from(ident, values), background=True)
                        self.sent[ident] = self.sent.get(ident, 0) + 1
                    except TopGimbalError as exc:
                        log.info("%s: %s feed not sent: %s", self.core.url, ident, exc)
            next_at += period_s
            delay = next_at - monotonic()
            if delay < 0:  # fell behind (a busy loop): carry on from now, never in a burst
                next_at, delay = monotonic(), 0.0
            await asyncio.sleep(delay)
