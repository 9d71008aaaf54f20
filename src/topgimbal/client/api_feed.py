"""Typed methods, part 4: what the host feeds the camera (the vehicle's position and the time), so
the camera can write them into its photos. The feeds themselves run in feeds.py.

`cam.feed(lat_deg, lon_deg, alt_m, heading_deg, time_utc=...)` gives a fix and / or the time once
(call it again with each new fix; a fix not renewed within feeds.FIX_MAX_AGE_S is no longer sent);
`cam.feed(fix=False)` says the vehicle has no fix. `cam.feed_from(source)` polls a callback
returning a `FeedSample` (or None) at `rate_hz` instead; the MAVLink bridge feeds from the
autopilot's messages (mavlink/camera_feed.py)."""

from __future__ import annotations

import asyncio
import datetime
import logging
from dataclasses import dataclass
from typing import Protocol, runtime_checkable

from ..errors import FieldValueError
from ..geo.earth import wrap180
from .core import ClientCore
from .feeds import FedPosition
from .methods import api_method

log = logging.getLogger("topgimbal.client")


@dataclass(frozen=True)
class FeedSample:
    """What a feed source knows now; None parts are left as they are (fix None: no fix)."""

    fix: FedPosition | None
    time_utc: datetime.datetime | None = None
    attitude_deg: tuple[float, float, float] | None = None  # vehicle roll, pitch, yaw


async def apply_sample(core: ClientCore, sample: FeedSample) -> None:
    """Hand one sample to the feeds (the bridge and `feed_from` use this)."""
    core.feeds.position(sample.fix)
    if sample.time_utc is not None:
        core.feeds.set_time(sample.time_utc, "feed source")
    spec = core.dialect.by_role("vehicle_attitude", core.model)
    # Only where the profile feeds it (C11, C12): a one-off acknowledged request per sample would
    # flood a model that takes the attitude as a setting.
    if sample.attitude_deg is not None and spec is not None and spec.ident in core.feeds.feeds():
        roll, pitch, yaw = sample.attitude_deg
        names = {f.name for f in spec.forms_for("w", "request")[0].fields}
        yaw = wrap180(yaw)
        given = {"yaw_deg": yaw, "pitch_deg": pitch, "roll_deg": roll}
        await core.feeds.vehicle_attitude({k: v for k, v in given.items() if k in names})


@runtime_checkable
class FeedSource(Protocol):
    """What `feed_from` polls: any callable taking nothing and returning a FeedSample or None."""

    def __call__(self) -> FeedSample | None: ...


class FeedMethods(Protocol):
    @api_method
    async def feed(
        core: ClientCore,
        lat_deg: float | None = None,
        lon_deg: float | None = None,
        alt_m: float | None = None,
        heading_deg: float | None = None,
        *,
        time_utc: datetime.datetime | None = None,
        fix: bool = True,
    ) -> dict[str, object]:
        """Feed the camera the vehicle's position (WGS84 degrees, altitude above mean sea level,
        true heading) and / or the UTC time, at the rates of the model's profile (`host_feeds`).
        `fix=False`: the vehicle has no fix, the position feeds stop. Returns what is fed now
        (`cam.feeds.status()`)."""
        given = (lat_deg, lon_deg, alt_m)
        if fix and any(v is not None for v in given):
            if any(v is None for v in given):
                raise FieldValueError("lat_deg", lat_deg, "lat_deg, lon_deg and alt_m together")
            assert lat_deg is not None and lon_deg is not None and alt_m is not None
            try:
                new = FedPosition(float(lat_deg), float(lon_deg), float(alt_m), heading_deg)
            except ValueError as exc:
                raise FieldValueError("lat_deg", (lat_deg, lon_deg, alt_m), str(exc)) from None
            if not core.feeds.position(new):
                log.info("%s: the %s takes no position feed", core.url, core.model.name)
        elif not fix:
            core.feeds.position(None)
        if time_utc is not None:
            if time_utc.tzinfo is None:
                raise FieldValueError("time_utc", time_utc, "a timezone-aware datetime (UTC)")
            core.feeds.set_time(time_utc)
        return core.feeds.status()

    @api_method
    async def feed_from(core: ClientCore, source: FeedSource, rate_hz: float = 10.0) -> None:
        """Poll `source()` at `rate_hz` in the background and feed what it returns (None: nothing
        new). Replaces an earlier source; stops when the client closes. A source that raises is
        logged and polled again at its next period."""
        if not (0.1 <= rate_hz <= 50.0):
            raise FieldValueError("rate_hz", rate_hz, "0.1..50 Hz")
        old = core.feeds.source_task
        if old is not None:
            old.cancel()
        core.feeds.source_task = asyncio.ensure_future(_poll(core, source, 1.0 / rate_hz))


async def _poll(core: ClientCore, source: FeedSource, period_s: float) -> None:
    while True:
        try:
            sample = source()
            if sample is not None:
                await apply_sample(core, sample)
        except asyncio.CancelledError:
            raise
        except Exception as exc:  # a user's callback: log, go on
            log.info("%s: feed source failed: %s", core.url, exc)
        await asyncio.sleep(period_s)
