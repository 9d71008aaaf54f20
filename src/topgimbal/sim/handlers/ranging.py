"""Laser rangefinder and the vehicle's position: flat-ground range from the gimbal's earth-frame
pitch and the altitude the host sent; TOPOTEK's target solution (§8.7) from position, heading,
attitude and range."""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

from ...protocol import Frame, Message
from .. import scene
from ..dispatch import Ctx, Refuse, handles
from .common import fields

if TYPE_CHECKING:
    from ..device import Device

CONTINUOUS_HZ = 1.0


def measure(dev: Device) -> float | None:
    """The distance the rangefinder reads now, or None (ERR) outside the model's range."""
    _, pitch, _ = dev.gimbal.earth()
    d = scene.slant_range(dev.position.alt_m, pitch)
    lo, hi = dev.model.lrf_range_m or (0.0, 0.0)
    if d is None or not lo <= d <= hi:
        return None
    return round(d, 1)


def target_frames(dev: Device, distance: float, host: str) -> list[Frame]:
    """§8.7: LAT / LON of the point the camera looks at (only once the host sent its position)."""
    pos = dev.position
    if pos.lat_deg is None or pos.lon_deg is None:
        return []
    yaw_body, _, _ = dev.gimbal.body()
    _, pitch, _ = dev.gimbal.earth()
    heading = pos.azimuth_deg if pos.azimuth_deg is not None else dev.gimbal.vehicle.yaw
    lat, lon = scene.target_position(pos.lat_deg, pos.lon_deg, heading + yaw_body, pitch, distance)
    out = []
    for ident, name, value in (("LAT", "lat_deg", lat), ("LON", "lon_deg", lon)):
        # notification() skips the echo form (ddmm.mmmm) and picks the §8.7 report (dd.dddddd).
        values: dict[str, Any] = {name: value}
        out.append(dev.dialect.notification(ident, src="D", dst=host, header="#tp", **values))
    return out


def result_frames(dev: Device, host: str) -> list[Frame]:
    d = measure(dev)
    frames = [dev.dialect.notification("LRF", src="D", dst=host, distance_m=d)]
    if d is not None:
        frames += target_frames(dev, d, host)
    return frames


@handles("LRF")
def lrf(dev: Device, msg: Message, ctx: Ctx) -> None:
    if dev.model.lrf_range_m is None:
        raise Refuse(f"the {dev.model.name} has no rangefinder")
    action = fields(msg)["action"]
    dev.camera.rangefinder = action
    if action == "single":
        for f in result_frames(dev, ctx.host):
            ctx.notify(f)
    dev.subscribe(ctx, "LRF", CONTINUOUS_HZ if action == "continuous" else 0.0)


@handles("SLR")
def slr(dev: Device, msg: Message, ctx: Ctx) -> dict[str, Any]:
    d = measure(dev)
    if d is None:
        raise Refuse("out of range")  # SkyDroid's SLR has no ERR token: the error frame
    return {"distance_m": d}


@handles("LAT")
def lat(dev: Device, msg: Message, ctx: Ctx) -> None:
    dev.position.lat_deg = float(fields(msg)["lat_deg"])


@handles("LON")
def lon(dev: Device, msg: Message, ctx: Ctx) -> None:
    dev.position.lon_deg = float(fields(msg)["lon_deg"])


@handles("ALT")
def alt(dev: Device, msg: Message, ctx: Ctx) -> None:
    dev.position.alt_m = float(fields(msg)["alt_m"])


@handles("AZI")
def azi(dev: Device, msg: Message, ctx: Ctx) -> None:
    dev.position.azimuth_deg = float(fields(msg)["azimuth_deg"])


@handles("GPS")
def gps(dev: Device, msg: Message, ctx: Ctx) -> None:
    f = fields(msg)
    pos = dev.position
    pos.lat_deg, pos.lon_deg, pos.alt_m = float(f["lat_deg"]), float(f["lon_deg"]), float(f["alt_m"])
    pos.azimuth_deg = float(f["heading_deg"]) % 360.0
