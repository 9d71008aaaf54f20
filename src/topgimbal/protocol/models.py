"""Device model profiles: everything known about one camera model, in one place.

A `DeviceModel` is data. The catalog, the simulator and the client all read it; nothing about a
model is written anywhere else. The profiles of each dialect live in `dialects/<dialect>_models.py`.

Fields (all optional beyond the first four):

    name, dialect, title      model name ("C12"), its dialect ("skydroid"), a title for people
    endpoints                 documented transports and ports (`Endpoint`): where a client connects
                              and the simulator listens by default
    alternate_endpoints       ports seen on real units beyond the documents (C12: UDP 12580)
    host_address              the address letter a host sends from ("U" uart/udp, TOPOTEK network "P")
    commands                  identifiers the model supports (None: every command of its dialect);
                              `DeviceModel.supports(ident)` reads it, `Dialect.supports` too
    yaw/pitch/roll_range_deg  mechanical range of each axis (a (0, 0) range: the axis is fixed)
    max_rate_deg_s            fastest slew; max_accel_deg_s2 its acceleration (simulator physics)
    thermal, visible_lenses   which imagers it has
    optical_zoom_max, digital_zoom_max, lrf_range_m    lens and rangefinder limits
    limits                    {(ident, field): (lo, hi)}: value ranges narrower than the codec's,
                              checked before sending (`Dialect.check_values`)
    wire_signs                wire sign per axis relative to the API convention (yaw right-, pitch
                              up-, roll right-positive): `{"pitch": -1}` for all kinds of quantity,
                              `{"rate.yaw": -1}` for one kind (`angle`, `rate`, `attitude`); see
                              `protocol.signs`
    dialect_options           how this model's firmware reads what the documents leave open
                              (`speed_unit_deg_s`...): `get_model()` builds its dialect with them
    destinations              {ident: address} where the model wants a command sent elsewhere than
                              the document says (C11: DZM to M)
    gimbal_header             header G-class frames must carry (C13: "#TP"; None: the dialect's rule)
    max_frame_bytes           longest frame the firmware takes (C11: 28 bytes); None: no known limit
    identity                  what the device reports, by role: {"version": "V1.2.0",
                              "model_name": "C12", "hardware_version": ...}; "role@ADDRESS" for
                              what one address answers differently (SIP "version@M": the lens)
    ignored                   commands the firmware silently drops: no effect, no echo
                              (C11: GAM, GSM, GAY, GAP: point by closing the loop over rates)
    no_echo                   writes the firmware often does not acknowledge: do not wait for an echo
    echo_rules                {ident: form title}: the form a write is answered with instead of a
                              plain echo (TOPOTEK REC / CAP feedback with a file index)
    slow_answers              queries that may be answered very late or never (C12 MOD): never block
                              other requests on them
    stop_repeats              how many times to send a stop (a stop may coast on some firmware)
    min_command_gap_s         least time between two commands (C12: 0.04 s)
    stream_rates_hz           {enabling command: Hz} the device streams at whatever was asked
                              (TOPOTEK GAA / GIA: 10 Hz; C11 GAA: 50 Hz); absent: as asked
    host_feeds                {ident: Hz} what a host should keep sending (C11: FAI 10 Hz, TIM 1 Hz)
    host_setup                ((ident, values), ...) frames a host sends once after connecting
                              (C11: FAE on before FAI)
    quirks                    {name: on by default in the simulator} for each known misbehaviour
                              (names and descriptions in `QUIRKS`)
    video                     video streams (`VideoStream`): URL per lens, field of view, zoom range
    sources                   public sources of the profile's facts (see docs/errata.md)
    notes                     free text for people

Per-device overrides: profiles are frozen dataclasses, so `dataclasses.replace(get_model("C12")[1],
wire_signs={"rate.yaw": -1})` gives a variant; `get_model(variant)` returns it with its dialect.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Any

from .fields import AXES, SIGN_KINDS

# Every misbehaviour a profile may name, with what it means. The simulator reproduces them (each
# switchable); the client copes with them by reading the profile fields they name.
QUIRKS: dict[str, str] = {
    "lowercase_header": "frames that would start #TP (replies, streams, errors) start #tp instead, as seen from "
    "TOPOTEK firmware",
    "crlf": "every frame the device sends ends with CR LF (some firmware does)",
    "no_motion_echo": "motion commands (the profile's no_echo set; every motion command where it names "
    "none) are obeyed but not echoed",
    "ver_wrong_length": "the VER reply's length character says 3 although it carries 6 characters (a real C12: "
    "#tpDU3rVER0105025A; the checksum covers all 6)",
    "ignored_commands": "the commands in the profile's ignored set are dropped: no effect and no echo",
    "stop_coasts": "a single stop is sometimes missed and the gimbal coasts on; a repeated stop halts it "
    "(the profile's stop_repeats)",
    "late_answers": "queries in the profile's slow_answers set are answered minutes late or not at all",
    "needs_video_output": "camera commands only take effect after video output has started",
    "no_clock": "the camera has no clock: its time is 1970-01-01 until the host sends TIM",
    "gimbal_header_required": "G-class frames with another header than the profile's gimbal_header are ignored",
    "command_pacing": "commands closer together than the profile's min_command_gap_s are dropped",
    "frame_size_limit": "frames longer than the profile's max_frame_bytes are dropped",
    "fixed_stream_rate": "streams go out at the profile's stream_rates_hz whatever rate the host asked for "
    "(C11: GAC at 50 Hz)",
    "wire_signs": "the profile's wire_signs apply (C11 / C12 / C13 GSY yaw inverted, SIP pitch down-positive); "
    "off: every value is signed as the document says",
    "speed_unit": "rate commands count in the profile's speed_unit_deg_s dialect option (C11: 0.5 deg/s per step, "
    "the document's table); off: the document text's 0.1 deg/s",
    "strict_destinations": "commands the profile's destinations move elsewhere (C11: DZM to M) are ignored when "
    "sent to the documented address",
    "version_digits_only": "the version is answered as digits only (123 for 1.2.3), as some firmware does",
}

TRANSPORTS = ("udp", "tcp", "serial")
LENSES = ("visible", "thermal", "mixed")


@dataclass(frozen=True)
class Endpoint:
    kind: str  # "udp", "tcp" or "serial"
    port: int | None = None
    note: str = ""

    def __post_init__(self) -> None:
        if self.kind not in TRANSPORTS:
            raise ValueError(f"endpoint kind {self.kind!r} is not one of {', '.join(TRANSPORTS)}")
        if self.port is not None and not 0 < self.port < 65536:
            raise ValueError(f"endpoint port {self.port} is not 1..65535")

    def __str__(self) -> str:
        return f"{self.kind.upper()} {self.port}" if self.port is not None else f"{self.kind} {self.note}".strip()


@dataclass(frozen=True)
class VideoStream:
    """One video stream: `url` with `{host}` for the camera's address; the lens it shows, its
    horizontal field of view at 1x and its optical zoom range, and where those facts come from."""

    name: str
    url: str
    lens: str = "visible"
    hfov_deg: float | None = None
    zoom_range_x: tuple[float, float] = (1.0, 1.0)
    source: str = ""

    def __post_init__(self) -> None:
        if self.lens not in LENSES:
            raise ValueError(f"video lens {self.lens!r} is not one of {', '.join(LENSES)}")
        if "{host}" not in self.url:
            raise ValueError(f"video url {self.url!r} has no {{host}} placeholder")

    def url_for(self, host: str) -> str:
        return self.url.replace("{host}", host)


def _empty() -> dict[str, Any]:
    return {}


@dataclass(frozen=True)
class DeviceModel:
    """One camera model's profile (see the module docstring for every field)."""

    name: str
    dialect: str
    title: str
    endpoints: tuple[Endpoint, ...]
    yaw_range_deg: tuple[float, float] = (-90.0, 90.0)
    pitch_range_deg: tuple[float, float] = (-90.0, 90.0)
    roll_range_deg: tuple[float, float] = (-90.0, 90.0)
    max_rate_deg_s: float = 60.0
    max_accel_deg_s2: float = 300.0
    thermal: bool = False
    visible_lenses: int = 1
    optical_zoom_max: float = 1.0
    digital_zoom_max: float = 4.0
    lrf_range_m: tuple[float, float] | None = None
    limits: Mapping[tuple[str, str], tuple[float, float]] = field(default_factory=dict)
    host_address: str = "U"
    wire_signs: Mapping[str, int] = field(default_factory=lambda: {"yaw": 1, "pitch": 1, "roll": 1})
    notes: str = ""
    commands: frozenset[str] | None = None
    alternate_endpoints: tuple[Endpoint, ...] = ()
    dialect_options: Mapping[str, Any] = field(default_factory=_empty)
    destinations: Mapping[str, str] = field(default_factory=dict)
    gimbal_header: str | None = None
    max_frame_bytes: int | None = None
    identity: Mapping[str, str] = field(default_factory=dict)
    ignored: frozenset[str] = frozenset()
    no_echo: frozenset[str] = frozenset()
    echo_rules: Mapping[str, str] = field(default_factory=dict)
    slow_answers: frozenset[str] = frozenset()
    stop_repeats: int = 1
    min_command_gap_s: float = 0.0
    stream_rates_hz: Mapping[str, float] = field(default_factory=dict)
    host_feeds: Mapping[str, float] = field(default_factory=dict)
    host_setup: tuple[tuple[str, Mapping[str, Any]], ...] = ()
    quirks: Mapping[str, bool] = field(default_factory=dict)
    video: tuple[VideoStream, ...] = ()
    sources: tuple[str, ...] = ()

    def __post_init__(self) -> None:
        where = f"model {self.name}"
        keys = set(AXES) | {f"{k}.{a}" for k in SIGN_KINDS for a in AXES}
        for key, sign in self.wire_signs.items():
            if key not in keys or sign not in (1, -1):
                raise ValueError(f"{where}: wire_signs {key!r}: {sign!r}; keys {', '.join(sorted(keys))}, signs 1 / -1")
        unknown = set(self.quirks) - set(QUIRKS)
        if unknown:
            raise ValueError(f"{where}: unknown quirk {sorted(unknown)[0]!r}; known: {', '.join(QUIRKS)}")
        if self.host_address not in ("U", "P") or self.stop_repeats < 1 or self.min_command_gap_s < 0:
            raise ValueError(f"{where}: host_address U|P, stop_repeats >= 1, min_command_gap_s >= 0")
        if self.max_frame_bytes is not None and self.max_frame_bytes < 12:
            raise ValueError(f"{where}: max_frame_bytes {self.max_frame_bytes} is below the smallest frame (12)")
        for ident, addr in self.destinations.items():
            if len(addr) != 1 or addr not in "MDEG":
                raise ValueError(f"{where}: destination of {ident} must be one of M, D, E, G")
        if self.commands is not None:
            named = self.ignored | self.no_echo | self.slow_answers | set(self.echo_rules) | set(self.destinations)
            stray = named - self.commands
            if stray:
                raise ValueError(f"{where}: {', '.join(sorted(stray))} named in the profile but not in its commands")

    # Profiles hold mappings (unhashable); two profiles of one name are the same model for hashing.
    def __hash__(self) -> int:
        return hash((self.name, self.dialect))

    def supports(self, ident: str) -> bool:
        """Whether the profile lists the command (the dialect must also have it)."""
        return self.commands is None or ident in self.commands

    def quirk_defaults(self) -> dict[str, bool]:
        """Every known quirk switch for this model: on where the profile says so, else off."""
        return {name: bool(self.quirks.get(name, False)) for name in QUIRKS}

    def video_stream(self, lens: str = "visible") -> VideoStream | None:
        return next((v for v in self.video if v.lens == lens), None)

    def describe(self) -> dict[str, Any]:
        """The profile as JSON-able data (the console, `topgimbal catalog --model`, docs)."""
        return {
            "name": self.name,
            "dialect": self.dialect,
            "title": self.title,
            "endpoints": [str(e) for e in self.endpoints],
            "alternate_endpoints": [str(e) for e in self.alternate_endpoints],
            "host_address": self.host_address,
            "yaw_range_deg": list(self.yaw_range_deg),
            "pitch_range_deg": list(self.pitch_range_deg),
            "roll_range_deg": list(self.roll_range_deg),
            "max_rate_deg_s": self.max_rate_deg_s,
            "thermal": self.thermal,
            "visible_lenses": self.visible_lenses,
            "optical_zoom_max": self.optical_zoom_max,
            "digital_zoom_max": self.digital_zoom_max,
            "lrf_range_m": list(self.lrf_range_m) if self.lrf_range_m else None,
            "limits": {f"{i}.{f}": list(r) for (i, f), r in self.limits.items()},
            "wire_signs": dict(self.wire_signs),
            "commands": sorted(self.commands) if self.commands is not None else None,
            "dialect_options": {k: v if isinstance(v, (int, float, str)) else str(v) for k, v in self.dialect_options.items()},
            "destinations": dict(self.destinations),
            "gimbal_header": self.gimbal_header,
            "max_frame_bytes": self.max_frame_bytes,
            "identity": dict(self.identity),
            "ignored": sorted(self.ignored),
            "no_echo": sorted(self.no_echo),
            "echo_rules": dict(self.echo_rules),
            "slow_answers": sorted(self.slow_answers),
            "stop_repeats": self.stop_repeats,
            "min_command_gap_s": self.min_command_gap_s,
            "stream_rates_hz": dict(self.stream_rates_hz),
            "host_feeds": dict(self.host_feeds),
            "host_setup": [[i, dict(v)] for i, v in self.host_setup],
            "quirks": dict(self.quirks),
            "video": [
                {"name": v.name, "url": v.url, "lens": v.lens, "hfov_deg": v.hfov_deg,
                 "zoom_range_x": list(v.zoom_range_x), "source": v.source}
                for v in self.video
            ],
            "sources": list(self.sources),
            "notes": self.notes,
        }  # fmt: skip


__all__ = ["LENSES", "QUIRKS", "TRANSPORTS", "DeviceModel", "Endpoint", "VideoStream"]
