"""Thermal imaging: temperature measurement from the synthetic scene. Palettes, scene mode,
shutter, detail, brightness, contrast, noise reduction and gamma are stored settings (each
dialect's table comes from its catalog; `next` / `previous` step through it)."""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

from ...protocol import Message
from .. import scene
from ..dispatch import Ctx, Refuse, handles
from .common import fields, setting

if TYPE_CHECKING:
    from ..device import Device

TMP_REPORT_HZ = 1.0


def _view(dev: Device) -> tuple[float, float]:
    y, p, _ = dev.gimbal.earth()
    return y, p


@handles("TMP")
def tmp(dev: Device, msg: Message, ctx: Ctx) -> dict[str, Any]:
    if not dev.model.thermal:
        raise Refuse(f"the {dev.model.name} has no thermal camera")
    y, p = _view(dev)
    f = fields(msg)
    if dev.dialect.name == "skydroid":
        # Layout undocumented (Appendix I): the simulator answers the centre temperature as
        # signed 16-bit hex in 0.01 °C, and subscribes the host to the same report once a second.
        dev.subscribe(ctx, "TMP", TMP_REPORT_HZ)
        return {"data": centre_hex(scene.temperature_at(y, p)).hex()}
    # TOPOTEK §12.3: spot / area query; the host is also subscribed to §12.1 reports.
    dev.subscribe(ctx, "TMP", TMP_REPORT_HZ)
    t = scene.area_temperature(y, p, f["x_px"], f["y_px"], f["width_px"], f["height_px"])
    return {**f, "avg_temp_c": t}


def centre_hex(t: float) -> bytes:
    raw = round(t * 100) & 0xFFFF
    return b"%04X" % raw


def tmp_report(dev: Device, host: str) -> Any:
    y, p = _view(dev)
    tf = scene.thermal_frame(y, p, dev.camera.thermal_digital_zoom_x)
    if dev.dialect.name == "skydroid":
        return dev.dialect.notification("TMP", src="D", dst=host, data=centre_hex(tf.center_c).hex())
    return dev.dialect.notification(
        "TMP",
        src="D",
        dst=host,
        hot_x_px=tf.hot_xy[0],
        hot_y_px=tf.hot_xy[1],
        hot_temp_c=tf.hot_c,
        center_temp_c=tf.center_c,
    )


@handles("TMR")
def tmr(dev: Device, msg: Message, ctx: Ctx) -> dict[str, Any] | None:
    dev.subscribe(ctx, "TMP", TMP_REPORT_HZ)
    return setting(dev, msg, ctx)
