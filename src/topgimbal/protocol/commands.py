"""Command specs: one identifier of one dialect, its forms and the metadata everyone reads.

Programs never branch on dialect names or identifiers to find "the version query" or "the SD card
command": they ask for a *role* (`dialect.by_role("version", model)`). Console panels group commands
by `group`. Both sets are closed and documented here; a spec with anything else is refused."""

from __future__ import annotations

import re
from collections.abc import Iterable, Mapping
from dataclasses import dataclass, field
from functools import cached_property
from typing import Any

from ..errors import UnsupportedError
from .forms import REQUEST, RESPONSE, Form
from .frame import Frame

_IDENT = re.compile(r"[A-Z0-9]{3}")

# What a command is for. Roles marked (many) may be held by several commands of one dialect (tell
# them apart by their fields' axes); every other role by at most one.
ROLES: dict[str, str] = {
    "error": "the device's answer to an invalid command (ERE)",
    # gimbal
    "gimbal_control": "discrete gimbal codes: stop, nudges, centre, follow / lock, calibration (PTZ)",
    "rate": "(many) gimbal rate command; its fields' axes say which axes",
    "angle": "(many) body-frame angle set-point; its fields' axes say which axes",
    "earth_angle": "(many) earth-frame angle set-point (TOPOTEK GI*)",
    "attitude": "body-frame attitude query and answer (GAC)",
    "attitude_stream": "turns the attitude stream on / off or sets its rate (GAA)",
    "earth_attitude": "earth-frame attitude query and answer (TOPOTEK GIC)",
    "earth_attitude_stream": "earth-frame attitude stream on / off, and the stream itself (TOPOTEK GIA)",
    "motors": "gimbal motors on / off",
    "vehicle_attitude": "the vehicle's attitude sent to the gimbal (FAI, UAV)",
    "vehicle_attitude_enable": "turns the vehicle attitude input on / off (FAE)",
    # tracking
    "tracking": "object tracking start / stop and state",
    "tracking_confirm": "tracking stop / confirm (SkyDroid SUM)",
    "tracking_target": "track the object at a picture position",
    "tracking_box": "tracking target box",
    # identity
    "version": "firmware / software version text",
    "model_name": "the model name the device reports",
    "hardware_version": "hardware version text",
    "serial_number": "serial number text",
    # camera
    "recording": "video recording start / stop / state",
    "photo": "take a photo",
    "sd_capacity": "SD card capacity",
    "resolution": "recording / stream resolution",
    "bitrate": "video stream bitrate",
    "encoding": "video encoding (H.264 / H.265)",
    "video_output": "video output parameters",
    "picture_in_picture": "picture-in-picture layout",
    "rotation": "image flip / rotation",
    "white_balance": "white balance",
    "image_params": "image style, hue, brightness ...",
    "exposure": "exposure compensation",
    "defog": "electronic defog",
    "day_night": "day / night (IR cut) mode",
    "osd": "on-screen display, LED and calibration switches (SkyDroid EXT)",
    # lens
    "zoom_control": "optical zoom in / out / stop",
    "zoom_position": "zoom motor position query",
    "zoom_focus_position": "set zoom and focus motor positions",
    "zoom_report": "magnification and zoom position report after each change",
    "optical_zoom": "optical magnification set / query",
    "digital_zoom": "digital zoom",
    "focus_control": "focus + / - / stop, auto / manual",
    "focus_position": "focus motor position query",
    "aperture": "aperture control",
    # thermal
    "palette": "thermal palette",
    "thermal_scene": "thermal scene mode",
    "thermal_shutter": "thermal shutter (flat-field correction) interval",
    "thermal_setting": "(many) one thermal image setting (detail, brightness, contrast, denoise, gamma)",
    "temperature": "temperature reports and spot / area measurement",
    "temperature_range": "radiometry range",
    # range
    "range": "laser range measurement (query or control, and the result)",
    # position and time
    "latitude": "vehicle latitude to the device; target latitude from it",
    "longitude": "vehicle longitude to the device; target longitude from it",
    "altitude": "vehicle altitude",
    "azimuth": "vehicle ground course",
    "vehicle_position": "vehicle position as one packed struct",
    "time": "local date and time",
    "utc_time": "UTC date and time",
    # network and system
    "ip_address": "camera IP address",
    "gateway": "camera gateway",
    "dns": "primary DNS server",
    "backup_dns": "backup DNS server",
    "network_reset": "reset the network settings",
    "reboot": "reboot or factory reset",
    "menu": "on-screen menu",
    "uid": "user id",
    "aux_power": "power an auxiliary device",
    "factory_test": "factory test (ATE) mode",
}
MANY_ROLES = frozenset(r for r, text in ROLES.items() if text.startswith("(many)"))

# Console panels (and `topgimbal catalog` sections).
GROUPS: dict[str, str] = {
    "gimbal": "gimbal motion, attitude and modes",
    "camera": "recording, photos, image and video settings",
    "lens": "zoom, focus, aperture",
    "thermal": "thermal image and radiometry",
    "range": "laser rangefinder",
    "tracking": "object tracking",
    "position": "vehicle position, attitude and time from the host",
    "network": "camera network settings",
    "system": "identity, errors, reboot and maintenance",
}


@dataclass(frozen=True)
class CommandSpec:
    """One identifier of one dialect, as data.

    `models` is filled in by the `Dialect` from its model profiles (None: every model); a spec
    built with `models` set keeps it as a restriction. `role` and `group` come from `ROLES` and
    `GROUPS`."""

    ident: str
    name: str
    title: str
    address: str  # default destination (device address class)
    forms: tuple[Form, ...]
    section: str  # where the document defines it ("SkyDroid §3.1", "beyond the documents: ...")
    models: frozenset[str] | None = None
    addresses: tuple[str, ...] = ()  # other destinations the command is also sent to
    header: str | None = None  # header the document uses for this command, when it insists
    documented: bool = True  # False for commands real clients use beyond the documents
    echo: bool = True  # writes are echoed by the device (the protocol's rule)
    repeatable: bool = True  # False: each write acts again (a photo), never retried
    motion: bool = False  # moves the gimbal (some firmware does not echo these)
    notes: str = ""
    role: str = ""
    group: str = ""
    _by_rw_direction: Mapping[tuple[str, str], tuple[Form, ...]] = field(
        init=False, repr=False, compare=False, default_factory=dict
    )

    def __post_init__(self) -> None:
        if not _IDENT.fullmatch(self.ident):
            raise ValueError(f"identifier {self.ident!r} is not 3 upper-case letters / digits")
        if self.role and self.role not in ROLES:
            raise ValueError(f"{self.ident}: role {self.role!r} is not one of {', '.join(ROLES)}")
        if self.group and self.group not in GROUPS:
            raise ValueError(f"{self.ident}: group {self.group!r} is not one of {', '.join(GROUPS)}")
        by: dict[tuple[str, str], tuple[Form, ...]] = {}
        for f in self.forms:
            by[(f.rw, f.direction)] = (*by.get((f.rw, f.direction), ()), f)
        object.__setattr__(self, "_by_rw_direction", by)

    def __repr__(self) -> str:
        """One line (the generated one printed every form and field: about 3 KB a command)."""
        return f"<CommandSpec {self.ident} {self.name}: {self.title!r}, {len(self.forms)} forms>"

    def describe(self) -> dict[str, Any]:
        """The command's metadata as JSON-able data; `models` is None when every model has it."""
        return {
            "id": self.ident,
            "name": self.name,
            "title": self.title,
            "address": self.address,
            "section": self.section,
            "role": self.role,
            "group": self.group,
            "models": sorted(self.models) if self.models is not None else None,
            "readable": self.readable,
            "writable": self.writable,
            "documented": self.documented,
            "repeatable": self.repeatable,
            "motion": self.motion,
            "notes": self.notes,
            "state_keys": self.state_keys,
            "forms": [f.describe() for f in self.forms],
        }

    @cached_property
    def signed_fields(self) -> tuple[tuple[str, str | None, int], ...]:
        """(name, axis, fixed sign) of every field with sign metadata; same-named fields of one
        command share it across forms. Computed once (read on the client's telemetry path)."""
        return tuple((name, axis, fixed) for name, _key, axis, fixed in self.wire_sign_fields)

    @cached_property
    def wire_sign_fields(self) -> tuple[tuple[str, str, str | None, int], ...]:
        """(name, sign key, axis, fixed sign) of every field with sign metadata, where the sign key
        is `"<sign_kind>.<axis>"` (`"rate.yaw"`), the entry of `protocol.signs.resolve_signs()`."""
        seen: dict[str, tuple[str, str, str | None, int]] = {}
        for form in self.forms:
            for f in form.fields:
                if (f.axis or f.sign != 1) and f.name not in seen:
                    seen[f.name] = (f.name, f"{f.sign_kind}.{f.axis}" if f.axis else "", f.axis, f.sign)
        return tuple(seen.values())

    @cached_property
    def state_keys(self) -> dict[str, str]:
        """Field name -> the client state cache key, for the fields that have one."""
        out: dict[str, str] = {}
        for form in self.forms:
            for f in form.fields:
                if f.state_key and f.name not in out:
                    out[f.name] = f.state_key
        return out

    @cached_property
    def axes(self) -> tuple[str, ...]:
        """The gimbal axes this command's request fields set (rate and angle commands)."""
        out: list[str] = []
        for form in self.forms_for("w", REQUEST):
            for f in form.fields:
                if f.axis and f.axis not in out:
                    out.append(f.axis)
        return tuple(out)

    def forms_for(self, rw: str, direction: str) -> list[Form]:
        return list(self._by_rw_direction.get((rw, direction), ()))

    def form(self, title: str, rw: str | None = None, direction: str | None = None) -> Form:
        """The form with this title (and control / direction, when given)."""
        for f in self.forms:
            if f.title == title and rw in (None, f.rw) and direction in (None, f.direction):
                return f
        titles = ", ".join(repr(f.title) for f in self.forms if direction in (None, f.direction))
        raise UnsupportedError(f"{self.ident} has no form {title!r}; its forms: {titles}")

    @property
    def readable(self) -> bool:
        return bool(self._by_rw_direction.get(("r", REQUEST)))

    @property
    def writable(self) -> bool:
        return bool(self._by_rw_direction.get(("w", REQUEST)))

    def request_form(self, rw: str, keys: Iterable[str] = ()) -> Form:
        forms = self._by_rw_direction.get((rw, REQUEST), ())
        if not forms:
            what = "read (r)" if rw == "r" else "written (w)"
            raise UnsupportedError(f"{self.ident} cannot be {what} by a host in this dialect")
        if len(forms) == 1:
            return forms[0]
        keys = set(keys)
        for f in forms:
            if keys <= f.names:
                return f
        return forms[0]

    def response_form(self, rw: str, data: bytes) -> Form | None:
        for f in self._by_rw_direction.get((rw, RESPONSE), ()):
            if f.accepts_length(len(data)):
                try:
                    f.decode(data)
                except ValueError:
                    continue
                return f
        return None

    def is_idempotent(self, frame: Frame) -> bool:
        """Whether sending `frame` twice has the effect of sending it once (safe to retry)."""
        if frame.rw == "r":
            return True
        if not self.repeatable:
            return False
        for f in self._by_rw_direction.get(("w", REQUEST), ()):
            if f.accepts_length(len(frame.data)):
                return f.is_idempotent(frame.data)
        return True


def stored_form(spec: CommandSpec) -> Form | None:
    """The form that holds a stored setting's values: the query's answer, else the write."""
    forms = spec.forms_for("r", RESPONSE) or spec.forms_for("w", REQUEST)
    return forms[0] if forms else None


def factory_values(spec_or_form: CommandSpec | Form) -> dict[str, Any]:
    """What a new device holds for a stored setting: each field's `factory` value, else its codec's
    neutral value (the first plain enum value, 0 clamped into the range...). For a command, the
    fields of its query answer (else of its write)."""
    form = stored_form(spec_or_form) if isinstance(spec_or_form, CommandSpec) else spec_or_form
    if form is None:
        return {}
    return {f.name: f.factory if f.factory is not None else f.codec.neutral() for f in form.fields}


__all__ = ["GROUPS", "MANY_ROLES", "ROLES", "CommandSpec", "factory_values", "stored_form"]
