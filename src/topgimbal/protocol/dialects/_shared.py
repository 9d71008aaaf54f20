"""Commands whose layout both documents share (or SkyDroid names only in its appendix and TOPOTEK
spells out), and the forms real clients send in both dialects. Each builder takes the section text
so each dialect cites its own document."""

from __future__ import annotations

from ..commands import CommandSpec
from ..fields import Codec, DecFloat, DecInt, Enum, Field, Geo, HexInt, IPv4Text, Literal, OneOf, enum
from ..forms import Form
from ._build import F, command, report, write_forms

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


def dzm_zoom(description: str = "magnification step 0.1 (decimal 00..80), or an action") -> Field:
    return F("zoom", OneOf(DZM_ACTIONS, DecInt(2, scale=0.1, unit="x", max=8.0)), description)


def digital_zoom_client_forms(*, two_char: bool) -> list[Form]:
    """DZM layouts public clients send beyond the documents (errata E30): a 2-character zoom
    (TOPOTEK only: SkyDroid's own 2-character form is documented), a 4-character image + zoom and a
    6-character image + magnification (4 decimal digits, 0.1x). Picked with `encode(form=title)` or
    by their field names."""
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


def error_frame(section: str) -> CommandSpec:
    return command(
        ident="ERE",
        name="error",
        title="Error answer to an invalid command",
        address="U",
        section=section,
        role="error",
        group="system",
        extra_forms=[report(F("error", Literal("!!"), "always '!!'"))],
        notes="The device answers an invalid command with #TP<dst><src>2wERE!! and the checksum.",
    )


def lens_commands(section: dict[str, str]) -> list[CommandSpec]:
    """Zoom / focus / day-night (TOPOTEK §三; SkyDroid lists them in Appendix I only)."""
    return [
        command(
            ident="ZMC",
            name="zoom_control",
            title="Optical zoom: in / out / stop",
            address="M",
            section=section["ZMC"],
            role="zoom_control",
            group="lens",
            write=[F("action", ZOOM_CONTROL, "in and out continue until stop")],
        ),
        command(
            ident="FCC",
            name="focus_control",
            title="Focus: + / - / stop, auto or manual",
            address="M",
            section=section["FCC"],
            role="focus_control",
            group="lens",
            write=[F("action", FOCUS_CONTROL, "+ and - continue until stop")],
        ),
        command(
            ident="ZFP",
            name="zoom_focus_position",
            title="Set zoom and focus positions",
            address="M",
            section=section["ZFP"],
            role="zoom_focus_position",
            group="lens",
            write=[
                F("zoom_pos", POSITION, "zoom motor position"),
                F(
                    "focus_pos",
                    HexInt(4, signed=True, none_tokens=(b"NNNN",)),
                    "focus motor position; null = autofocus after the zoom",
                    default=None,
                ),
            ],
        ),
        command(
            ident="IRC",
            name="day_night",
            title="Day / night (IR cut) mode",
            address="M",
            section=section["IRC"],
            role="day_night",
            group="camera",
            write=[F("mode", DAY_NIGHT)],
        ),
    ]


# A new camera's network settings: TOPOTEK §五.7 gives the address and gateway RST restores; the
# DNS servers are our assumption (the gateway, and a public resolver), documented in errata E34.
NETWORK_FACTORY = {
    "ip": "192.168.144.108",
    "gateway": "192.168.144.10",
    "dns": "192.168.144.10",
    "backup_dns": "8.8.8.8",
}


def network_commands(section: dict[str, str], *, dns: bool = True) -> list[CommandSpec]:
    def ip(key: str) -> list[Field]:
        return [F("address", IPv4Text(), state_key=f"network.{key}", factory=NETWORK_FACTORY[key])]

    def addr(ident: str, name: str, title: str, key: str, notes: str = "") -> CommandSpec:
        return command(
            ident=ident,
            name=name,
            title=title,
            address="D",
            section=section[ident],
            role=name,
            group="network",
            write=ip(key),
            read=ip(key),
            header="#tp",
            notes=notes,
        )

    out = [
        addr(
            "IPV",
            "ip_address",
            "Camera IP address",
            "ip",
            "Changing it moves the camera: a client must reconnect to the new address.",
        ),
        addr("GTW", "gateway", "Camera gateway", "gateway"),
    ]
    if dns:
        out += [
            addr("DNS", "dns", "Primary DNS server", "dns"),
            addr("BNS", "backup_dns", "Backup DNS server", "backup_dns"),
        ]
    out.append(
        command(
            ident="RST",
            name="network_reset",
            title="Reset the network configuration to defaults",
            address="D",
            section=section["RST"],
            role="network_reset",
            group="network",
            write=[
                F(
                    "action",
                    enum(
                        2,
                        {
                            "01": ("reset", "Reset network settings"),
                            "00": ("keep", "Keep the network settings (sent by some clients)"),
                        },
                    ),
                )
            ],
            notes="TOPOTEK: defaults ip 192.168.144.108, gateway 192.168.144.10 (documented, never used in tests). "
            "00 is sent by public clients; its meaning is not documented: treated as no reset (errata E30).",
        ),
    )
    return out


def position_commands(section: dict[str, str], *, target: bool = True) -> list[CommandSpec]:
    """Vehicle position from the host (NMEA-style text), and the target solution from the device."""
    tgt = f"{section['LAT']} (target solution)"

    def target_report(name: str, codec: Codec, what: str) -> list[Form]:
        if not target:
            return []
        return [report(F(name, codec, f"target {what}"), title="target solution", section=tgt)]

    def coordinate(ident: str, axis: str, what: str, negative: str, pattern: str) -> CommandSpec:
        return command(
            ident=ident,
            name=what,
            title=f"Vehicle {what} ({pattern}); target {what} from the device",
            address="D",
            section=section[ident],
            role=what,
            group="position",
            write=[F(f"{axis}_deg", Geo(axis, "dm"), f"vehicle {what}, {negative} negative")],
            extra_forms=target_report(f"{axis}_deg", Geo(axis, "deg"), what),
        )

    return [
        coordinate("LAT", "lat", "latitude", "south", "ddmm.mmmm"),
        coordinate("LON", "lon", "longitude", "west", "dddmm.mmmm"),
        command(
            ident="ALT",
            name="altitude",
            title="Vehicle altitude",
            address="D",
            section=section["ALT"],
            role="altitude",
            group="position",
            write=[F("alt_m", DecFloat(None, 1, "m", -9999.9, 9999.9, pad=8), "altitude above mean sea level")],
        ),
    ]


def on_off_codec() -> Enum:
    return enum(2, {"00": "off", "01": "on"})


__all__ = [
    "BEYOND",
    "DZM_ACTIONS",
    "digital_zoom_client_forms",
    "dzm_zoom",
    "error_frame",
    "lens_commands",
    "network_commands",
    "on_off_codec",
    "palette_channel_forms",
    "position_commands",
]
