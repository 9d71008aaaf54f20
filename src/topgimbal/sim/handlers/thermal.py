"""Temperature measurement from the synthetic scene. Palettes, scene mode, shutter, detail,
brightness, contrast, noise reduction and gamma are stored settings (`common.setting`; each
dialect's table comes from its catalog, `next` / `previous` step through it). The two dialects'
TMP commands share an identifier and nothing else: each has its handler in its dialect's table."""

from __future__ import annotations

from typing import Any

from ...protocol import Frame, Message
from .. import scene
from ..context import RefusedError, Request, SimState
from ..streams import Stream
from .common import fields, setting

TMP_REPORT_HZ = 1.0


def _view(state: SimState) -> tuple[float, float]:
    y, p, _ = state.gimbal.earth()
    return y, p


def _need_thermal(state: SimState) -> None:
    if not state.model.thermal:
        raise RefusedError(f"the {state.model.name} has no thermal camera")


def centre_hex(t: float) -> str:
    """Signed 16-bit hex in 0.01 °C, as the data bytes' hex text."""
    return (b"%04X" % (round(t * 100) & 0xFFFF)).hex()


def centre_report(state: SimState, s: Stream) -> list[Frame]:
    return [
        state.dialect.notification(s.ident, src="D", dst=s.host, data=centre_hex(scene.temperature_at(*_view(state))))
    ]


def centre_temperature(state: SimState, msg: Message, req: Request) -> dict[str, Any]:
    """SkyDroid TMP (layout undocumented, Appendix I): the centre temperature as signed 16-bit hex
    in 0.01 °C; the host is subscribed to the same report once a second."""
    _need_thermal(state)
    assert msg.spec is not None
    state.subscribe(req, msg.spec.ident, TMP_REPORT_HZ, centre_report)
    return {"data": centre_hex(scene.temperature_at(*_view(state)))}


def hot_report(state: SimState, s: Stream) -> list[Frame]:
    """TOPOTEK §12.2: hottest and coldest points and centre of the thermal picture (the fuller of
    the document's two periodic reports, §12.1 lacking the coldest point: a ground station's
    thermal range needs both ends; docs/errata.md)."""
    y, p = _view(state)
    tf = scene.thermal_frame(y, p, state.camera.thermal_digital_zoom_x)
    return [
        state.dialect.notification(
            s.ident,
            src="D",
            dst=s.host,
            hot_x_px=tf.hot_xy[0],
            hot_y_px=tf.hot_xy[1],
            hot_temp_c=tf.hot_c,
            cold_x_px=tf.cold_xy[0],
            cold_y_px=tf.cold_xy[1],
            cold_temp_c=tf.cold_c,
            center_temp_c=tf.center_c,
        )
    ]


def area_temperature(state: SimState, msg: Message, req: Request) -> dict[str, Any]:
    """TOPOTEK §12.3 spot / area query; the host is also subscribed to §12.2 reports."""
    _need_thermal(state)
    assert msg.spec is not None
    f = fields(msg)
    state.subscribe(req, msg.spec.ident, TMP_REPORT_HZ, hot_report)
    y, p = _view(state)
    return {**f, "avg_temp_c": scene.area_temperature(y, p, f["x_px"], f["y_px"], f["width_px"], f["height_px"])}


def temperature_range(state: SimState, msg: Message, req: Request) -> dict[str, Any] | None:
    """TMR: a stored setting; switching it starts the §12.2 reports too."""
    report = state.dialect.by_role("temperature", state.model)
    if report is not None:
        state.subscribe(req, report.ident, TMP_REPORT_HZ, hot_report)
    return setting(state, msg, req)
