"""Commands whose layout both documents share (or SkyDroid names only in its appendix and TOPOTEK
spells out), and the forms real clients send in both dialects. Each builder takes the section text
so each dialect cites its own document."""

from __future__ import annotations

from collections.abc import Iterable, Mapping
from dataclasses import replace
from typing import Any

from ..commands import CommandSpec
from ..dialect import Dialect
from ..fields import DecFloat, DecInt, Enum, Field, Geo, HexInt, IPv4Text, Literal, OneOf, enum
from ..fields.enums import EnumSpec
from ..forms import Form
from ..models import DeviceModel
from ._build import F, command, place, rate, report, write_forms

ZOOM_CONTROL = enum(2, {"00": "stop", "01": ("zoom_out", "Zoom out (wide)"), "02": ("zoom_in", "Zoom in (tele)")})
FOCUS_CONTROL = enum(
    2,
    {
        "00": "stop",
        "01": ("focus_plus", "Focus +"),
        "02": ("focus_minus", "Focus -"),
        "10": ("auto", "Auto focus"),
        "11": ("manual", "Manual focus"),
        "12": ("manual_save", "Manual focus (saved)"),
        "13": ("auto_save", "Auto focus (saved)"),
    },
)
DAY_NIGHT = enum(2, {"00": "day", "01": "night", "0A": ("toggle", "Toggle day/night")}, toggles="0A")
POSITION = HexInt(4, signed=True)
# Digital zoom actions as TOPOTEK §五.14 spells them; also the token table of the forms public
# clients send in both dialects (errata E30).
DZM_ACTIONS = enum(
    2,
    {
        "0A": ("step_in", "Zoom in 0.5x"),
        "0B": ("step_out", "Zoom out 0.5x"),
        "0C": ("zoom_in", "Zoom in until stop"),
        "0D": ("zoom_out", "Zoom out until stop"),
        "0E": "stop",
    },
    toggles=("0A", "0B"),
)
# Which image the client forms zoom. Not called `lens` like TOPOTEK's 1-character field: code that
# tells the two documented layouts apart by that name keeps working.
DZM_IMAGE = enum(2, {"00": "visible", "01": "thermal"})
BEYOND = "beyond the documents"
REC_ACTION = enum(2, {"00": "stop", "01": "start", "0A": ("toggle", "Toggle")}, toggles="0A")
REC_STATE = enum(2, {"00": ("stopped", "Not recording"), "01": ("recording", "Recording")})
# PTZ codes both documents number alike; they swap 06 (follow / lock) and 07, and differ from 0A on.
PTZ_SHARED: dict[str, EnumSpec] = {
    "00": "stop",
    "01": ("up", "Nudge up"),
    "02": ("down", "Nudge down"),
    "03": ("left", "Nudge left"),
    "04": ("right", "Nudge right"),
    "05": ("center", "Centre", "回中"),
    "08": ("toggle_follow_lock", "Toggle follow / lock"),
    "09": ("calibrate", "Gimbal calibration"),
}


def ptz_actions(own: dict[str, EnumSpec], toggles: tuple[str, ...] = ()) -> Enum:
    """The PTZ action table: the shared codes plus a document's own, in code order."""
    codes = dict(sorted({**PTZ_SHARED, **own}.items()))
    return enum(2, codes, toggles=("01", "02", "03", "04", "08", "09", *toggles))


def dzm_zoom(description: str = "magnification step 0.1 (decimal 00..80), or an action") -> Field:
    return F("zoom", OneOf(DZM_ACTIONS, DecInt(2, scale=0.1, unit="x", max=8.0)), description)


def digital_zoom_client_forms(*, two_char: bool) -> list[Form]:
    """DZM layouts public clients send beyond the documents (errata E30): a 2-character zoom
    (TOPOTEK only: SkyDroid's own 2-character form is documented), a 4-character image + zoom, a
    6-character image + magnification (4 decimal digits, 0.1x) and a 6-character image code + `F` +
    ratio (3 hex digits, 0.1x). Picked with `encode(form=title)` or by their field names."""
    section = f"{BEYOND} (public clients; layout inferred)"
    forms: list[Form] = []
    if two_char:
        forms += write_forms([dzm_zoom()], "zoom (2 characters)", section=section)
    forms += write_forms([F("image", DZM_IMAGE), dzm_zoom()], "image and zoom (4 characters)", section=section)
    forms += write_forms(
        [F("image", DZM_IMAGE), F("magnification_x", DecInt(4, scale=0.1, unit="x", max=99.9))],
        "image and magnification (6 characters)",
        section=section,
    )
    # A public C13 ground station's absolute zoom ("PROTOCAL §14.1", errata E30): image code, `F`,
    # the ratio in 0.1x as three hex digits (14x -> 00F08C); it sends image codes beyond 00 / 01.
    forms += write_forms(
        [
            F("image_code", HexInt(2), "image / camera: 00 visible, 01 thermal, others as the model numbers them"),
            F("ratio_mark", Literal("F"), "always F: a zoom ratio follows", default="F"),
            F("ratio_x", HexInt(3, scale=0.1, unit="x", max=409.5), "zoom ratio in 0.1x (three hex digits)"),
        ],
        "image code and ratio (F + 3 hex digits)",
        section=f"{BEYOND} (public C13 ground station, 'PROTOCAL §14.1')",
    )
    return forms


def palette_channel_forms(palettes: Enum) -> list[Form]:
    """IMG with 4 characters (public clients, errata E30): a thermal channel (00 on single-thermal
    models) before the document's 2-character palette code."""
    section = f"{BEYOND} (public clients; layout inferred)"
    fields = [F("channel", HexInt(2), "thermal channel, 00 on single-thermal models"), F("palette", palettes)]
    return [
        *write_forms(fields, "channel and palette (4 characters)", section=section),
        report(*fields, rw="r", title="answer with channel (4 characters)", section=section),
    ]


def rate_commands(
    section: str, u: float, steps: int, notes: dict[str, str], *, gsm_notes: bool, **gsm: Any
) -> list[CommandSpec]:
    """GSY / GSP / GSR / GSM: one axis rate, or yaw and pitch together (`gsm`: more keywords of the
    GSM row). `notes` per axis; `gsm_notes`: whether GSM's fields carry them too."""

    def row(ident: str, name: str, title: str, fields: list[Field], **kw: Any) -> CommandSpec:
        return command(ident=ident, name=name, title=title, section=section, role="rate", write=fields,
                       motion=True, **place("G", "gimbal"), **kw)  # fmt: skip

    def axis(name: str, noted: bool = True) -> Field:
        return rate(name, u, steps, notes.get(name, "") if noted else "")

    return [
        row("GSY", "yaw_rate", "Yaw speed", [axis("yaw")]),
        row("GSP", "pitch_rate", "Pitch speed", [axis("pitch")]),
        row("GSR", "roll_rate", "Roll speed", [axis("roll")]),
        row("GSM", "yaw_pitch_rate", "Yaw and pitch speed", [axis("yaw", gsm_notes), axis("pitch", gsm_notes)], **gsm),
    ]


def recording_command(section: str, extra_forms: list[Form] | None = None) -> CommandSpec:
    return command(ident="REC", name="recording", title="Start / stop / toggle recording; query state",
                   section=section, role="recording", write=[F("action", REC_ACTION)],
                   read=[F("state", REC_STATE, state_key="recording")], extra_forms=extra_forms or (),
                   **place("D", "camera"))  # fmt: skip


def palette_command(section: str, palettes: Enum) -> CommandSpec:
    return command(ident="IMG", name="palette", title="Thermal palette", section=section, role="palette",
                   write=[F("palette", palettes)], read=[F("palette", palettes, state_key="palette", factory="white_hot")],
                   extra_forms=palette_channel_forms(palettes), **place("D", "thermal"))  # fmt: skip


def error_frame(section: str) -> CommandSpec:
    return command(ident="ERE", name="error", title="Error answer to an invalid command", address="U", section=section,
                   role="error", group="system", extra_forms=[report(F("error", Literal("!!"), "always '!!'"))],
                   notes="The device answers an invalid command with #TP<dst><src>2wERE!! and the checksum.")  # fmt: skip


def lens_commands(section: dict[str, str]) -> list[CommandSpec]:
    """Zoom / focus / day-night (TOPOTEK §三; SkyDroid lists them in Appendix I only), each a write
    to the lens (M) whose role is its name."""

    def row(ident: str, name: str, title: str, fields: list[Field], group: str = "lens") -> CommandSpec:
        return command(ident=ident, name=name, title=title, address="M", section=section[ident], role=name,
                       group=group, write=fields)  # fmt: skip

    focus_pos = HexInt(4, signed=True, none_tokens=(b"NNNN",))
    return [
        row("ZMC", "zoom_control", "Optical zoom: in / out / stop",
            [F("action", ZOOM_CONTROL, "in and out continue until stop")]),
        row("FCC", "focus_control", "Focus: + / - / stop, auto or manual",
            [F("action", FOCUS_CONTROL, "+ and - continue until stop")]),
        row("ZFP", "zoom_focus_position", "Set zoom and focus positions",
            [F("zoom_pos", POSITION, "zoom motor position"),
             F("focus_pos", focus_pos, "focus motor position; null = autofocus after the zoom", default=None)]),
        row("IRC", "day_night", "Day / night (IR cut) mode", [F("mode", DAY_NIGHT)], group="camera"),
    ]  # fmt: skip


# A new camera's network settings: TOPOTEK §五.7 gives the address and gateway RST restores; the
# DNS servers are our assumption (the gateway, and a public resolver), documented in errata E34.
NETWORK_FACTORY = {
    "ip": "192.168.144.108",
    "gateway": "192.168.144.10",
    "dns": "192.168.144.10",
    "backup_dns": "8.8.8.8",
}


def network_commands(section: dict[str, str], *, dns: bool = True) -> list[CommandSpec]:
    """Camera network settings (to the camera, D), each command's role its name."""

    def row(ident: str, name: str, title: str, notes: str = "", **kw: Any) -> CommandSpec:
        return command(ident=ident, name=name, title=title, address="D", section=section[ident], role=name,
                       group="network", notes=notes, **kw)  # fmt: skip

    def addr(ident: str, name: str, title: str, key: str, notes: str = "") -> CommandSpec:
        ip = [F("address", IPv4Text(), state_key=f"network.{key}", factory=NETWORK_FACTORY[key])]
        return row(ident, name, title, notes, write=ip, read=ip, header="#tp")

    reset = enum(2, {"01": ("reset", "Reset network settings"),
                     "00": ("keep", "Keep the network settings (sent by some clients)")})  # fmt: skip
    out = [
        addr("IPV", "ip_address", "Camera IP address", "ip",
             "Changing it moves the camera: a client must reconnect to the new address."),
        addr("GTW", "gateway", "Camera gateway", "gateway"),
    ]  # fmt: skip
    if dns:
        out += [
            addr("DNS", "dns", "Primary DNS server", "dns"),
            addr("BNS", "backup_dns", "Backup DNS server", "backup_dns"),
        ]
    out.append(
        row("RST", "network_reset", "Reset the network configuration to defaults",
            "TOPOTEK: defaults ip 192.168.144.108, gateway 192.168.144.10 (documented, never used in tests). "
            "00 is sent by public clients; its meaning is not documented: treated as no reset (errata E30).",
            write=[F("action", reset)])
    )  # fmt: skip
    return out


def position_commands(section: dict[str, str], *, target: bool = True) -> list[CommandSpec]:
    """Vehicle position from the host (NMEA-style text), and the target solution from the device."""
    tgt = f"{section['LAT']} (target solution)"

    def row(ident: str, name: str, title: str, **kw: Any) -> CommandSpec:
        return command(ident=ident, name=name, title=title, address="D", section=section[ident], role=name,
                       group="position", **kw)  # fmt: skip

    def coordinate(ident: str, axis: str, what: str, negative: str, pattern: str) -> CommandSpec:
        answer = F(f"{axis}_deg", Geo(axis, "deg"), f"target {what}")
        return row(ident, what, f"Vehicle {what} ({pattern}); target {what} from the device",
                   write=[F(f"{axis}_deg", Geo(axis, "dm"), f"vehicle {what}, {negative} negative")],
                   extra_forms=[report(answer, title="target solution", section=tgt)] if target else [])  # fmt: skip

    altitude = F("alt_m", DecFloat(None, 1, "m", -9999.9, 9999.9, pad=8), "altitude above mean sea level")
    return [
        coordinate("LAT", "lat", "latitude", "south", "ddmm.mmmm"),
        coordinate("LON", "lon", "longitude", "west", "dddmm.mmmm"),
        row("ALT", "altitude", "Vehicle altitude", write=[altitude]),
    ]


def build_dialect(
    name: str,
    title: str,
    commands: list[CommandSpec],
    models: Iterable[DeviceModel],
    *,
    max_rate_deg_s: float,
    options: dict[str, object],
    destinations: Mapping[str, str] | None,
    **kw: Any,
) -> Dialect:
    """A dialect with its builder's options. A profile's max rate follows the builder's speed unit
    (`max_rate_deg_s`) unless the profile fixes the unit itself."""
    models = [
        m if "speed_unit_deg_s" in m.dialect_options else replace(m, max_rate_deg_s=max_rate_deg_s) for m in models
    ]
    if destinations:
        options = {**options, "destinations": dict(destinations)}
    return Dialect(name, title, commands, models, options=options, destinations=destinations, **kw)


def on_off_codec() -> Enum:
    return enum(2, {"00": "off", "01": "on"})


__all__ = [
    "BEYOND",
    "DZM_ACTIONS",
    "REC_ACTION",
    "REC_STATE",
    "build_dialect",
    "digital_zoom_client_forms",
    "dzm_zoom",
    "error_frame",
    "lens_commands",
    "network_commands",
    "on_off_codec",
    "palette_channel_forms",
    "palette_command",
    "position_commands",
    "ptz_actions",
    "rate_commands",
    "recording_command",
]
