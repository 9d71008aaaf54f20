"""Laser range and the vehicle's position: flat-ground range from the gimbal's earth-frame pitch and
the altitude the host sent; the target solution (TOPOTEK §8.7) from position, heading, attitude and
range. SkyDroid's SLR (a query) and TOPOTEK's LRF (control and reports) share the `range` role and
little else: each has its handler in its dialect's table."""

from __future__ import annotations

from typing import Any

from ...geo.earth import wrap360
from ...protocol import RESPONSE, Frame, Message
from .. import scene
from ..context import RefusedError, Request, SimState
from ..streams import Stream
from .common import fields

CONTINUOUS_HZ = 1.0


def measure(state: SimState, limit_m: float | None = None) -> float | None:
    """The distance the rangefinder reads now, or None outside the model's range (or `limit_m`).
    On a terrain model (sim --terrain) the ray starts at the fed position (ALT above mean sea
    level) and needs all of LAT, LON and ALT; on flat ground ALT is the height above it."""
    _, pitch, _ = state.gimbal.earth()
    lo, hi = state.model.lrf_range_m or (0.0, 0.0)
    if limit_m is not None:
        hi = min(hi, limit_m)
    pos = state.position
    if state.terrain is not None:
        if pos.lat_deg is None or pos.lon_deg is None or pos.alt_m is None:
            return None
        d = state.terrain.slant_range(pos.lat_deg, pos.lon_deg, pos.alt_m, ray_bearing(state), pitch, hi)
    else:
        d = scene.slant_range(pos.alt_m, pitch)
    if d is None or not lo <= d <= hi:
        return None
    return round(d, 1)


def ray_bearing(state: SimState) -> float:
    """Earth-frame bearing of the optical axis: the heading (AZI, else the vehicle's yaw) plus the
    gimbal's body yaw, as the target solution (§8.7) counts it."""
    pos = state.position
    yaw_body, _, _ = state.gimbal.body()
    heading = pos.azimuth_deg if pos.azimuth_deg is not None else state.gimbal.vehicle.yaw
    return heading + yaw_body


def target_frames(state: SimState, distance: float, host: str) -> list[Frame]:
    """§8.7: LAT / LON of the point the camera looks at (only once the host sent its position)."""
    pos = state.position
    if pos.lat_deg is None or pos.lon_deg is None:
        return []
    out = []
    for role in ("latitude", "longitude"):
        spec = state.dialect.by_role(role, state.model)
        if spec is None or not any(f.title == "target solution" for f in spec.forms):
            return []
        out.append(spec)
    _, pitch, _ = state.gimbal.earth()
    lat, lon = scene.target_position(pos.lat_deg, pos.lon_deg, ray_bearing(state), pitch, distance)
    # notification() passes the echo form (ddmm.mmmm) over and picks the §8.7 report (dd.dddddd).
    return [
        state.dialect.notification(out[0].ident, src="D", dst=host, header="#tp", lat_deg=lat),
        state.dialect.notification(out[1].ident, src="D", dst=host, header="#tp", lon_deg=lon),
    ]


def result_frames(state: SimState, ident: str, host: str) -> list[Frame]:
    d = measure(state)
    frames = [state.dialect.notification(ident, src="D", dst=host, distance_m=d)]
    if d is not None:
        frames += target_frames(state, d, host)
    return frames


def result_report(state: SimState, s: Stream) -> list[Frame]:
    return result_frames(state, s.ident, s.host)


def rangefinder(state: SimState, msg: Message, req: Request) -> None:
    """TOPOTEK LRF: 02 one result, 03 one a second until 00; results (and the target solution
    after a good one) follow the echo."""
    assert msg.spec is not None
    if state.model.lrf_range_m is None:
        raise RefusedError(f"the {state.model.name} has no rangefinder")
    action = fields(msg)["action"]
    state.camera.rangefinder = action
    if action == "single":
        for f in result_frames(state, msg.spec.ident, req.host):
            req.notify(f)
    state.subscribe(req, msg.spec.ident, CONTINUOUS_HZ if action == "continuous" else 0.0, result_report)


def laser_range(state: SimState, msg: Message, req: Request) -> dict[str, Any] | None:
    """SkyDroid SLR: a query answers one measurement (no ERR token: out of range is the error
    frame); a write sets the measuring range limit, which later queries honour, or fires one
    measurement (`measure`, public clients), which the next query reads."""
    assert msg.spec is not None
    if state.model.lrf_range_m is None:
        raise RefusedError(f"the {state.model.name} has no rangefinder")
    store = state.settings.setdefault(msg.spec.ident, {})
    if req.frame.rw == "w":
        if fields(msg).get("action") == "measure":
            return None  # fire one measurement: every query measures anew here
        store.update(fields(msg))
        state.dirty = True
        return None
    d = measure(state, store.get("limit_m"))
    if d is None:
        raise RefusedError("nothing in range")
    return {msg.spec.forms_for("r", RESPONSE)[0].fields[0].name: d}


def latitude(state: SimState, msg: Message, req: Request) -> None:
    state.position.lat_deg = float(fields(msg)["lat_deg"])


def longitude(state: SimState, msg: Message, req: Request) -> None:
    state.position.lon_deg = float(fields(msg)["lon_deg"])


def altitude(state: SimState, msg: Message, req: Request) -> None:
    state.position.alt_m = float(fields(msg)["alt_m"])


def azimuth(state: SimState, msg: Message, req: Request) -> None:
    state.position.azimuth_deg = float(fields(msg)["azimuth_deg"])


def vehicle_position(state: SimState, msg: Message, req: Request) -> None:
    f = fields(msg)
    pos = state.position
    pos.lat_deg, pos.lon_deg, pos.alt_m = float(f["lat_deg"]), float(f["lon_deg"]), float(f["alt_m"])
    pos.azimuth_deg = wrap360(float(f["heading_deg"]))
