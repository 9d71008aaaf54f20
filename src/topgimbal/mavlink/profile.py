"""What MAVLink needs to know about a camera model, derived from the catalog.

Nothing here is a second model table: every fact is read from the dialect's command specs
(`supports()`, `describe()`) and the model profile (`DeviceModel`: limits, identity, video
streams). Streams and lenses are read through `video.lens` (pure), the one place that turns the
profile's `VideoStream`s into URLs, ports and fields of view for the simulator, the SDK's
`video_url()` and this bridge alike."""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

from ..protocol import DeviceModel, Dialect
from ..video.lens import StreamSpec, VideoError, stream_urls, streams_for


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
    extra: dict[str, Any] = field(default_factory=dict)

    def has(self, ident: str) -> bool:
        return ident in self.supported

    # -- gimbal ------------------------------------------------------------------------------------

    @property
    def has_yaw(self) -> bool:
        return self.has("GAY") or self.has("GAM")

    @property
    def has_pitch(self) -> bool:
        return self.has("GAP") or self.has("GAM")

    @property
    def has_roll(self) -> bool:
        return self.has("GAR")

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
        return self.has("GIY")

    # -- camera ------------------------------------------------------------------------------------

    @property
    def can_photo(self) -> bool:
        return self.has("CAP")

    @property
    def can_record(self) -> bool:
        return self.has("REC")

    @property
    def has_sd(self) -> bool:
        return self.has("SDC")

    @property
    def zoom_continuous(self) -> bool:
        return self.has("ZMC") and {"zoom_in", "zoom_out", "stop"} <= self.zoom_actions

    @property
    def zoom_max_x(self) -> float:
        """Largest magnification an absolute zoom command reaches (optical where it can be set,
        else digital)."""
        if self.has("MUL"):
            return max(1.0, self.model.optical_zoom_max)
        if self.has("DZM"):
            return max(1.0, self.model.digital_zoom_max)
        return 1.0

    @property
    def zoom_absolute(self) -> bool:
        return self.zoom_max_x > 1.0

    @property
    def can_focus(self) -> bool:
        return self.has("FCC")

    @property
    def track_point(self) -> bool:
        return self.has("GOT") or (self.has("TRC") and self.has("LOC"))

    @property
    def track_rectangle(self) -> bool:
        return self.has("TRC") and self.has("LOC")

    @property
    def rangefinder(self) -> tuple[float, float] | None:
        if self.model.lrf_range_m is None or not (self.has("SLR") or self.has("LRF")):
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
    supported = frozenset(c.ident for c in dialect.supported(model))
    rate_fields = {f["name"]: f for form in _forms(dialect, "GAA") for f in form["fields"]}
    stream_max = rate_fields["rate_hz"].get("max") if "rate_hz" in rate_fields else None
    return Profile(
        model=model,
        dialect=dialect,
        vendor=dialect.title.split()[0] if dialect.title else dialect.name,
        supported=supported,
        ptz_actions=enum_names(dialect, "PTZ", "action") if "PTZ" in supported else frozenset(),
        photo_modes=enum_names(dialect, "CAP", "mode") if "CAP" in supported else frozenset(),
        zoom_actions=enum_names(dialect, "ZMC", "action") if "ZMC" in supported else frozenset(),
        focus_actions=enum_names(dialect, "FCC", "action") if "FCC" in supported else frozenset(),
        digital_zoom_has_lens="lens" in field_names(dialect, "DZM"),
        stream_max_hz=float(stream_max) if stream_max else None,
    )


def _forms(dialect: Dialect, ident: str) -> list[dict[str, Any]]:
    spec = dialect.commands.get(ident)
    if spec is None:
        return []
    return [f for f in spec.describe()["forms"] if f["rw"] == "w" and f["direction"] == "request"]
