"""`cam.locate()`: where the camera looks, from what the client knows or asks now.

The ray: bearing = the vehicle's heading (the fix's, or `heading_deg`) plus the gimbal's body
yaw, elevation = the gimbal's earth-frame pitch where the model reports one (gravity-referenced;
its earth-frame yaw is not used: gimbals without a compass count it from where they woke up), else
the body pitch (a level vehicle). This is TOPOTEK's own target solution (§8.7). The lens: the
profile's visible stream, its field of view narrowed by the zoom the client last saw."""

from __future__ import annotations

import os
from collections.abc import Awaitable, Callable
from pathlib import Path
from typing import Any

from ..errors import FieldValueError, TopGimbalError
from ..geo import Attitude, Fix, Geodetic, Pointing, Terrain, Uncertainty, View, locate
from ..geo.earth import wrap360
from ..geo.optics import hfov_at, vfov_for
from ..protocol.streams import stream_for
from . import roles
from .api_core import request
from .core import ClientCore
from .state import GimbalAttitude

# Terrain models read from files, by (path, modification time): at most this many are kept.
MAX_CACHED_DEMS = 4
_dems: dict[tuple[str, float], Terrain] = {}


def terrain_from(path: str | Path) -> Terrain:
    """The DEM at `path` (read once per modification; DemError for a file it cannot use)."""
    from ..geo.dem import load_dem

    p = os.fspath(path)
    try:
        key = (p, os.stat(p).st_mtime)
    except OSError as e:
        raise TopGimbalError(f"{p}: cannot read a DEM: {e.strerror}") from None
    if key not in _dems:
        while len(_dems) >= MAX_CACHED_DEMS:
            _dems.pop(next(iter(_dems)))
        _dems[key] = load_dem(p)
    return _dems[key]


def _zoom_x(core: ClientCore) -> float:
    z = core.state.zoom
    try:
        return max(1.0, float(z.value)) if z is not None else 1.0  # type: ignore[arg-type]
    except (TypeError, ValueError):
        return 1.0


async def _send_position(core: ClientCore, fix: Geodetic, heading_deg: float | None) -> None:
    """Tell the camera where the vehicle is now, acknowledged, so its laser's target solution and
    the simulator's terrain ray start there (the feeds would send it only at their next period)."""
    values: dict[str, dict[str, Any]] = {
        "latitude": {"lat_deg": fix.lat_deg},
        "longitude": {"lon_deg": fix.lon_deg},
        "altitude": {"alt_m": fix.alt_m},
    }
    if heading_deg is not None:
        values["azimuth"] = {"azimuth_deg": wrap360(heading_deg)}
    for role, v in values.items():
        ident = roles.role_ident(core.dialect, core.model, role)
        if ident is not None:
            await request(core, ident, **v)


async def locate_now(
    core: ClientCore,
    *,
    terrain: Terrain | str | Path | None,
    laser: bool,
    ground_alt_m: float | None,
    position: tuple[float, float, float] | None,
    heading_deg: float | None,
    uncertainty: Uncertainty,
    measure_range: Callable[[], Awaitable[float | None]],
) -> tuple[Fix | None, dict[str, object]]:
    """The fix (None: nothing known to be hit) and what it was computed from."""
    fed = core.feeds.fix
    if position is not None:
        lat, lon, alt = (float(v) for v in position)
        pos = Geodetic(lat, lon, alt)
    elif fed is not None:
        pos = Geodetic(fed.lat_deg, fed.lon_deg, fed.alt_m)
    else:
        raise FieldValueError(
            "position", None, "the vehicle's position: feed() one first or pass position=(lat, lon, alt)"
        )
    heading = (
        heading_deg if heading_deg is not None else (fed.heading_deg if fed is not None and position is None else None)
    )
    if heading is None:
        raise FieldValueError(
            "heading_deg", None, "the vehicle's heading (degrees from true north): feed() it or pass it"
        )
    model = terrain_from(terrain) if isinstance(terrain, (str, Path)) else terrain

    body = await core_get_attitude(core, earth=False)
    earth = None
    if roles.role_ident(core.dialect, core.model, "earth_attitude") is not None:
        earth = await core_get_attitude(core, earth=True)
    pitch = earth.pitch_deg if earth is not None else body.pitch_deg
    roll = earth.roll_deg if earth is not None else body.roll_deg
    stream = stream_for(core.model)
    zoom = _zoom_x(core)
    hfov = hfov_at(stream.hfov_deg, zoom)
    view = View(
        pos,
        Attitude(yaw_deg=heading),
        Pointing(wrap360(heading + body.yaw_deg), pitch, roll, earth_frame=True),
        hfov,
        vfov_for(hfov, *stream.size),
    )
    laser_m: float | None = None
    if laser:
        if position is not None:
            await _send_position(core, pos, heading)
        laser_m = await measure_range()
    fix = locate(view, terrain=model, laser_range_m=laser_m, ground_alt_m=ground_alt_m, uncertainty=uncertainty)
    inputs: dict[str, object] = {
        "vehicle": {"lat_deg": pos.lat_deg, "lon_deg": pos.lon_deg, "alt_m": pos.alt_m, "heading_deg": heading},
        "gimbal": {
            "yaw_deg": body.yaw_deg,
            "pitch_deg": pitch,
            "pitch_frame": "earth" if earth is not None else "body",
        },
        "hfov_deg": round(view.hfov_deg, 3),
        "vfov_deg": round(view.vfov_deg, 3),
        "zoom_x": zoom,
        "laser_m": laser_m,
        "terrain": os.fspath(terrain)
        if isinstance(terrain, (str, Path))
        else ("given" if terrain is not None else None),
    }
    return fix, inputs


async def core_get_attitude(core: ClientCore, *, earth: bool) -> GimbalAttitude:
    from .api_core import CoreMethods

    return await CoreMethods.get_attitude.fn(core, earth=earth)
