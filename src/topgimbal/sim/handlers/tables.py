"""The handler tables. `handler_table(dialect)` is what a `Device` dispatches on: identifier ->
handler, built from one explicit table by catalog role (what both dialects do alike) and one table
per dialect (identifiers whose two documents share a role and little else). An identifier in
neither is a stored setting. Nothing registers itself on import; a caller may pass its own table."""

from __future__ import annotations

from collections.abc import Mapping
from types import MappingProxyType

from ...protocol import Dialect
from ..context import Handler
from . import camera, gimbal, lens, ranging, system, thermal
from .common import refuse, setting

BY_ROLE: Mapping[str, Handler] = MappingProxyType(
    {
        "error": refuse,
        "zoom_report": refuse,
        # gimbal
        "gimbal_control": gimbal.control,
        "rate": gimbal.rates,
        "angle": gimbal.angles,
        "earth_angle": gimbal.angles,
        "attitude": gimbal.body_attitude,
        "earth_attitude": gimbal.earth_attitude,
        "attitude_stream": gimbal.attitude_stream,
        "earth_attitude_stream": gimbal.earth_attitude_stream,
        "motors": gimbal.motors,
        "vehicle_attitude": gimbal.vehicle_attitude,
        "vehicle_attitude_enable": gimbal.vehicle_attitude_enable,
        "tracking": gimbal.tracking,
        "tracking_confirm": gimbal.tracking_confirm,
        "tracking_target": gimbal.tracking_target,
        "tracking_box": gimbal.tracking_box,
        # identity and system
        "version": camera.identity,
        "model_name": camera.identity,
        "hardware_version": camera.identity,
        "serial_number": camera.identity,
        "uid": camera.uid,
        "ip_address": system.address,
        "gateway": system.address,
        "dns": system.address,
        "backup_dns": system.address,
        "network_reset": system.network_reset,
        "reboot": system.reboot,
        # camera
        "recording": camera.recording,
        "photo": camera.photo,
        "sd_capacity": camera.sd_card,
        "video_output": camera.video_output,
        "bitrate": camera.bitrate,
        "time": camera.set_time,
        "utc_time": camera.set_time,
        # lens
        "zoom_control": lens.zoom_control,
        "zoom_position": lens.zoom_position,
        "zoom_focus_position": lens.zoom_focus_position,
        "optical_zoom": lens.magnification,
        "digital_zoom": lens.digital_zoom,
        "focus_control": lens.focus_control,
        "focus_position": lens.focus_position,
        "day_night": lens.day_night,
        # thermal
        "temperature_range": thermal.temperature_range,
        # position
        "latitude": ranging.latitude,
        "longitude": ranging.longitude,
        "altitude": ranging.altitude,
        "azimuth": ranging.azimuth,
        "vehicle_position": ranging.vehicle_position,
    }
)

# Identifiers whose dialects disagree on what they are.
SKYDROID: Mapping[str, Handler] = MappingProxyType(
    {
        "TMP": thermal.centre_temperature,  # Appendix I, layout undocumented: a centre reading
        "SLR": ranging.laser_range,  # §4.22: a query per measurement, a write sets the limit
    }
)
TOPOTEK: Mapping[str, Handler] = MappingProxyType(
    {
        "TMP": thermal.area_temperature,  # §五.12: spot / area queries and periodic reports
        "LRF": ranging.rangefinder,  # §五.9: on / single / continuous, results sent unasked
    }
)
DIALECT_TABLES: Mapping[str, Mapping[str, Handler]] = MappingProxyType({"skydroid": SKYDROID, "topotek": TOPOTEK})


def handler_table(dialect: Dialect, overrides: Mapping[str, Handler] | None = None) -> Mapping[str, Handler]:
    """Every identifier of `dialect` -> its handler: the dialect's own table, else its role's
    handler, else a stored setting; then `overrides` (a caller's additions or replacements)."""
    own = DIALECT_TABLES.get(dialect.name, {})
    table = {ident: own.get(ident) or BY_ROLE.get(spec.role, setting) for ident, spec in dialect.commands.items()}
    table.update(overrides or {})
    return MappingProxyType(table)


__all__ = ["BY_ROLE", "DIALECT_TABLES", "SKYDROID", "TOPOTEK", "handler_table"]
