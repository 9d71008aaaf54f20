"""What MAVLink needs to know about a camera model, derived from the catalog.

Nothing here is a second model table: every fact is read from the dialect's command specs,
found by role (`by_role()`, `describe()`, the fields' axes), and the model profile (`DeviceModel`: limits, identity, video
streams). Streams and lenses are read through `video.lens` (pure), the one place that turns the
profile's `VideoStream`s into URLs, ports and fields of view for the simulator, the SDK's
`video_url()` and this bridge alike."""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

from ..protocol import DeviceModel, Dialect
from ..protocol.streams import StreamSpec, VideoError, stream_urls, streams_for


def enum_names(dialect: Dialect, ident: str, field_name: str, rw: str = "w") -> frozenset[str]:
    """Names an enum field of a host -> device form accepts, from the catalog's own description."""
    spec = dialect.commands.get(ident)
    if spec is None:
        return frozenset()
    out: set[str] = set()
    for form in spec.describe()["forms"]:
        if form["rw"] != rw or form["direction"] != "request":
            continue
        for f in form["fields"]:
            if f["name"] == field_name:
                out.update(v["name"] for v in f.get("values", ()))
                out.update(v["name"] for v in (f.get("tokens") or {}).get("values", ()))
    return frozenset(out)


def field_names(dialect: Dialect, ident: str, rw: str = "w", direction: str = "request") -> frozenset[str]:
    spec = dialect.commands.get(ident)
    if spec is None:
        return frozenset()
    return frozenset(f.name for form in spec.forms_for(rw, direction) for f in form.fields)


@dataclass(frozen=True)
class Profile:
    model: DeviceModel
    dialect: Dialect
    vendor: str
    supported: frozenset[str]
    ptz_actions: frozenset[str]
    photo_modes: frozenset[str]
    zoom_actions: frozenset[str]
    focus_actions: frozenset[str]
    digital_zoom_has_lens: bool
    stream_max_hz: float | None
    roles: frozenset[str] = frozenset()  # roles of the commands the model supports (`protocol.ROLES`)
    angle_axes: frozenset[str] = frozenset()  # axes the model's angle set-points cover
    rate_axes: frozenset[str] = frozenset()  # axes its rate commands cover
    extra: dict[str, Any] = field(default_factory=dict)

    def can(self, role: str) -> bool:
        """Whether the model supports a command holding `role` (found by role, never by name)."""
        return role in self.roles

    def ident(self, role: str) -> str:
        """The identifier of the model's command for `role` (UnsupportedError when none)."""
        return self.dialect.require_role(role, self.model).ident

    # -- gimbal ------------------------------------------------------------------------------------

    @property
    def has_yaw(self) -> bool:
        return "yaw" in self.angle_axes

    @property
    def has_pitch(self) -> bool:
        return "pitch" in self.angle_axes

    @property
    def has_roll(self) -> bool:
        return "roll" in self.angle_axes

    @property
    def has_follow(self) -> bool:
        return "follow" in self.ptz_actions

    @property
    def has_lock(self) -> bool:
        return "lock" in self.ptz_actions

    @property
    def has_neutral(self) -> bool:
        return "center" in self.ptz_actions

    @property
    def earth_frame(self) -> bool:
        return self.can("earth_angle")

    # -- camera ------------------------------------------------------------------------------------

    @property
    def can_photo(self) -> bool:
        return self.can("photo")

    @property
    def can_record(self) -> bool:
        return self.can("recording")

    @property
    def has_sd(self) -> bool:
        return self.can("sd_capacity")

    @property
    def zoom_continuous(self) -> bool:
        return self.can("zoom_control") and {"zoom_in", "zoom_out", "stop"} <= self.zoom_actions

    @property
    def zoom_max_x(self) -> float:
        """Largest magnification an absolute zoom command reaches (optical where it can be set,
        else digital)."""
        if self.can("optical_zoom"):
            return max(1.0, self.model.optical_zoom_max)
        if self.can("digital_zoom"):
            return max(1.0, self.model.digital_zoom_max)
        return 1.0

    @property
    def zoom_absolute(self) -> bool:
        return self.zoom_max_x > 1.0

    @property
    def can_focus(self) -> bool:
        return self.can("focus_control")

    @property
    def track_point(self) -> bool:
        return self.can("tracking_target") or self.track_rectangle

    @property
    def track_rectangle(self) -> bool:
        return self.can("tracking_box")

    @property
    def rangefinder(self) -> tuple[float, float] | None:
        if self.model.lrf_range_m is None or not self.can("range"):
            return None
        return self.model.lrf_range_m

    @property
    def thermal(self) -> bool:
        return self.model.thermal

    def thermal_photo_mode(self) -> str | None:
        return "thermal" if "thermal" in self.photo_modes else None

    def streams(self) -> dict[str, StreamSpec]:
        """The model's video streams by lens (visible first), from its profile."""
        try:
            return {s.lens: s for s in streams_for(self.model)}
        except VideoError:
            return {}

    def lens(self, which: str = "visible") -> StreamSpec | None:
        """A lens's stream: field of view at 1x (horizontal from the profile, vertical derived
        from the picture's aspect ratio), picture size, zoom range."""
        return self.streams().get(which)

    def rtsp_urls(self, camera_host: str | None, *, port: int | None = None) -> dict[str, str]:
        """{lens: RTSP URL} at the camera's address (none without one: a serial link); `port`
        moves the first stream's port and keeps the others' spacing, as `sim --video-port`."""
        if not camera_host or not self.streams():
            return {}
        return stream_urls(self.model, camera_host, port=port)


def profile_of(dialect: Dialect, model: DeviceModel) -> Profile:
    specs = dialect.supported(model)
    supported = frozenset(c.ident for c in specs)
    roles = frozenset(c.role for c in specs if c.role)

    def ident(role: str) -> str:
        spec = dialect.by_role(role, model)
        return spec.ident if spec is not None else ""

    def axes(role: str) -> frozenset[str]:
        return frozenset(
            f.axis
            for spec in dialect.commands_with_role(role, model)
            for form in spec.forms_for("w", "request")
            for f in form.fields
            if f.axis
        )

    rate_fields = {f["name"]: f for form in _forms(dialect, ident("attitude_stream")) for f in form["fields"]}
    stream_max = rate_fields["rate_hz"].get("max") if "rate_hz" in rate_fields else None
    return Profile(
        model=model,
        dialect=dialect,
        vendor=dialect.title.split()[0] if dialect.title else dialect.name,
        supported=supported,
        ptz_actions=enum_names(dialect, ident("gimbal_control"), "action"),
        photo_modes=enum_names(dialect, ident("photo"), "mode"),
        zoom_actions=enum_names(dialect, ident("zoom_control"), "action"),
        focus_actions=enum_names(dialect, ident("focus_control"), "action"),
        digital_zoom_has_lens="lens" in field_names(dialect, ident("digital_zoom")),
        stream_max_hz=float(stream_max) if stream_max else None,
        roles=roles,
        angle_axes=axes("angle"),
        rate_axes=axes("rate"),
    )


def _forms(dialect: Dialect, ident: str) -> list[dict[str, Any]]:
    spec = dialect.commands.get(ident)
    if spec is None:
        return []
    return [f for f in spec.describe()["forms"] if f["rw"] == "w" and f["direction"] == "request"]
