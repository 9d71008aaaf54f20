"""Commands whose layout both documents share (or SkyDroid names only in its appendix and TOPOTEK
spells out). Each builder takes the section text so each dialect cites its own document."""

from __future__ import annotations

from ..catalog import CommandSpec
from ..fields import DecFloat, Enum, GeoDeg, GeoDM, HexInt, IPv4Text, Literal, enum
from ._build import QUERY, F, report, spec

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


def error_frame(section: str) -> CommandSpec:
    return spec(
        "ERE",
        "error",
        "Error answer to an invalid command",
        "U",
        section,
        extra_forms=[report(F("error", Literal("!!"), "always '!!'"))],
        notes="The device answers an invalid command with #TP<dst><src>2wERE!! and the checksum.",
    )


def lens_commands(section: dict[str, str], models: frozenset[str] | None = None) -> list[CommandSpec]:
    """Zoom / focus / day-night (TOPOTEK §三; SkyDroid lists them in Appendix I only)."""
    return [
        spec(
            "ZMC",
            "zoom_control",
            "Optical zoom: in / out / stop",
            "M",
            section["ZMC"],
            write=[F("action", ZOOM_CONTROL, "in and out continue until stop")],
            models=models,
        ),
        spec(
            "FCC",
            "focus_control",
            "Focus: + / - / stop, auto or manual",
            "M",
            section["FCC"],
            write=[F("action", FOCUS_CONTROL, "+ and - continue until stop")],
            models=models,
        ),
        spec(
            "ZFP",
            "zoom_focus_position",
            "Set zoom and focus positions",
            "M",
            section["ZFP"],
            write=[
                F("zoom_pos", POSITION, "zoom motor position"),
                F(
                    "focus_pos",
                    HexInt(4, signed=True, none_tokens=(b"NNNN",)),
                    "focus motor position; null = autofocus after the zoom",
                    default=None,
                ),
            ],
            models=models,
        ),
        spec(
            "IRC",
            "day_night",
            "Day / night (IR cut) mode",
            "M",
            section["IRC"],
            write=[F("mode", DAY_NIGHT)],
            models=models,
        ),
    ]


def network_commands(
    section: dict[str, str], models: frozenset[str] | None = None, dns: bool = True
) -> list[CommandSpec]:
    ip = [F("address", IPv4Text())]
    out = [
        spec(
            "IPV",
            "ip_address",
            "Camera IP address",
            "D",
            section["IPV"],
            write=ip,
            read=ip,
            header="#tp",
            models=models,
            notes="Changing it moves the camera: a client must reconnect to the new address.",
        ),
        spec("GTW", "gateway", "Camera gateway", "D", section["GTW"], write=ip, read=ip, header="#tp", models=models),
    ]
    if dns:
        out += [
            spec(
                "DNS", "dns", "Primary DNS server", "D", section["DNS"], write=ip, read=ip, header="#tp", models=models
            ),
            spec(
                "BNS",
                "backup_dns",
                "Backup DNS server",
                "D",
                section["BNS"],
                write=ip,
                read=ip,
                header="#tp",
                models=models,
            ),
        ]
    out.append(
        spec(
            "RST",
            "network_reset",
            "Reset the network configuration to defaults",
            "D",
            section["RST"],
            write=[F("action", enum(2, {"01": ("reset", "Reset network settings")}))],
            models=models,
            notes="TOPOTEK: defaults ip 192.168.144.108, gateway 192.168.144.10 (documented, never used in tests).",
        ),
    )
    return out


def position_commands(
    section: dict[str, str], models: frozenset[str] | None = None, target: bool = True
) -> list[CommandSpec]:
    """Vehicle position from the host (NMEA-style text), and the target solution from the device."""
    lat_target = (
        [report(F("lat_deg", GeoDeg("lat"), "target latitude (§8.7)"), title="target solution")] if target else []
    )
    lon_target = (
        [report(F("lon_deg", GeoDeg("lon"), "target longitude (§8.7)"), title="target solution")] if target else []
    )
    return [
        spec(
            "LAT",
            "latitude",
            "Vehicle latitude (ddmm.mmmm); target latitude from the device",
            "D",
            section["LAT"],
            write=[F("lat_deg", GeoDM("lat"), "vehicle latitude, south negative")],
            extra_forms=lat_target,
            models=models,
        ),
        spec(
            "LON",
            "longitude",
            "Vehicle longitude (dddmm.mmmm); target longitude from the device",
            "D",
            section["LON"],
            write=[F("lon_deg", GeoDM("lon"), "vehicle longitude, west negative")],
            extra_forms=lon_target,
            models=models,
        ),
        spec(
            "ALT",
            "altitude",
            "Vehicle altitude",
            "D",
            section["ALT"],
            write=[F("alt_m", DecFloat(None, 1, "m", -9999.9, 9999.9, pad=8), "altitude above mean sea level")],
            models=models,
        ),
    ]


def on_off_codec() -> Enum:
    return enum(2, {"00": "off", "01": "on"})


__all__ = ["QUERY", "error_frame", "lens_commands", "network_commands", "on_off_codec", "position_commands"]
