"""SkyDroid "TOP 协议" V1.1.5 (C10, C10Pro, C12, C13, C20; and the C11 from public reports).

The command table is data: one keyword-only row per identifier. Which model supports what is not
here but in each model's profile (`skydroid_models.py`), from each section's 支持 line. Commands the
document names only in Appendix I take TOPOTEK's layout (errata E13).
"""

from __future__ import annotations

from collections.abc import Mapping

from ..commands import CommandSpec
from ..dialect import Dialect
from ..fields import Field, HexInt, RawData, Text, Timestamp, enum
from . import _shared as shared
from ._build import F, angle, attitude_fields, command, level, place, report, write_forms
from .skydroid_models import MODELS

DOC = "SkyDroid"
TITLE = 'SkyDroid "TOP 协议" V1.1.5'
APPENDIX = f"{DOC} Appendix I (layout not given; TOPOTEK's assumed)"
CLIENTS = f"{shared.BEYOND} (public clients: ArduPilot's SkyDroid driver, ground stations)"
RATE_STEPS = 127

PTZ = shared.ptz_actions(
    {
        "06": ("follow", "Follow", "跟随"),
        "07": ("lock", "Lock heading", "锁头"),
        "0A": ("mount_hanging", "Hanging (under-slung) mount", "吊装"),
        "0B": ("mount_inverted", "Inverted (upright) mount", "倒装"),
        "0C": ("calibrate_horizontal", "Horizontal calibration"),
        "0D": ("calibrate_vertical", "Vertical calibration"),
        "0E": ("trim_x_plus", "Trim X+"),
        "0F": ("trim_x_minus", "Trim X-"),
        "10": ("trim_y_plus", "Trim Y+"),
        "11": ("trim_y_minus", "Trim Y-"),
        "12": ("trim_z_plus", "Trim Z+"),
        "13": ("trim_z_minus", "Trim Z-"),
        "14": ("trim_clear", "Clear trims"),
    },
    toggles=("0C", "0D", "0E", "0F", "10", "11", "12", "13"),
)
LENS_RES = enum(1, {"0": "720p", "1": "1080p", "2": "2k", "3": "4k", "N": ("null", "No change / no lens")})
AWB = enum(
    1,
    {
        "0": "auto",
        "1": "night",
        "2": "incandescent",
        "3": "fluorescent",
        "4": "warm_fluorescent",
        "5": "daylight",
        "6": "cloudy_daylight",
        "7": "twilight",
        "8": "shade",
        "A": ("awb_plus", "AWB +"),
        "B": ("awb_minus", "AWB -"),
        "N": ("null", "No change / no lens"),
    },
    toggles=("A", "B"),
)
PALETTES = enum(
    2,
    {
        "01": ("white_hot", "White hot", "白热"),
        "03": ("sepia", "Sepia", "辉金"),
        "04": ("ironbow", "Ironbow", "铁红"),
        "05": ("rainbow", "Rainbow", "彩虹"),
        "06": ("night", "Night", "微光"),
        "07": ("aurora", "Aurora", "极光"),
        "08": ("red_hot", "Red hot", "红热"),
        "09": ("jungle", "Jungle", "丛林"),
        "0A": ("medical", "Medical", "医疗"),
        "0B": ("black_hot", "Black hot", "黑热"),
        "0C": ("glory_hot", "Glory hot", "金红"),
    },
)
SCENES = enum(
    2,
    {
        "00": ("general", "General", "通用"),
        "03": ("low_temp_highlight", "Low-temperature highlight", "低温突出"),
        "04": ("linear_stretch", "Linear stretch", "线性拉伸"),
        "05": ("low_contrast", "Low contrast", "低对比度"),
        "06": ("high_contrast", "High contrast", "高对比度"),
        "07": ("highlight", "Highlight", "高亮突出"),
    },
)
BIT1 = enum(1, {"0": "off", "1": "on"})
IQE_STYLE = enum(1, {"0": "custom", "1": "standard", "2": "bright", "3": "vivid"})
DIGITAL_ZOOM = enum(
    2,
    {"01": "1x", "02": "2x", "03": "3x", "04": "4x", "0A": ("zoom_in", "Zoom +"), "0B": ("zoom_out", "Zoom -")},
    toggles=("0A", "0B"),
)
FLIGHT_MODE = enum(2, {"00": ("hover", "Multirotor / hover"), "01": ("fixed_wing", "Fixed wing")})


def _image_params() -> list[Field]:
    return [
        F("lens", HexInt(1), "lens id", default=0),
        F("style", IQE_STYLE, factory="standard"),
        *(level(n, 255, factory=128) for n in ("hue", "brightness", "saturation", "contrast", "sharpness")),
    ]


def _video_output() -> list[Field]:
    return [
        F("h_flip", BIT1),
        F("v_flip", BIT1),
        F("fps", HexInt(2, min=1, max=60, unit="fps"), factory=30),
        F("gop", HexInt(2, min=1, max=255, unit="frames"), "frames between key frames", factory=30),
        F("bitrate_kbps", HexInt(4, min=100, max=10240, unit="kbps"), factory=4000),
        F("output", BIT1, "video data output", factory="on"),
    ]


def _extended(write: bool) -> list[Field]:
    return [
        F("reserved", enum(1, {"0": "zero"}), default="zero" if write else None),
        F("dish_calibration", BIT1, default="off" if write else None),
        F("osd", BIT1, factory="on"),
        F("led", BIT1, factory="off"),
    ]


def commands(u: float) -> list[CommandSpec]:
    """Every SkyDroid command, as data. `u`: the GS* rate step in deg/s (errata E7)."""
    sp = F("speed_deg_s", HexInt(2, scale=0.1, unit="deg/s", max=9.9), "slew speed 0..99 x 0.1 deg/s", default=9.9)
    yaw = angle("yaw_deg", -90, 90, "yaw, right-positive")
    pitch = angle("pitch_deg", -90, 90, "pitch, up-positive")
    roll = angle("roll_deg", -90, 90, "roll (struck out in V1.0.7: not supported for now)")
    s33 = f"{DOC} §3.3.1"
    on_off = shared.on_off_codec()
    raw = [F("data", RawData(None, max_bytes=15), "layout not documented")]
    gimbal = place("G", "gimbal")
    camera = place("D", "camera")
    thermal = place("D", "thermal")
    return [
        shared.error_frame(f"{DOC} §2.3.2"),
        # -- G class: gimbal ---------------------------------------------------------------------
        command(ident="PTZ", name="gimbal_control", title="Gimbal control codes", section=f"{DOC} §3.1",
                role="gimbal_control", write=[F("action", PTZ)], motion=True, **gimbal),
        *shared.rate_commands(f"{DOC} §3.2", u, RATE_STEPS, {"yaw": "right positive", "pitch": "up positive"},
                       gsm_notes=False),
        command(ident="GAY", name="yaw_angle", title="Yaw angle", section=s33, role="angle", write=[yaw, sp],
                motion=True, **gimbal),
        command(ident="GAP", name="pitch_angle", title="Pitch angle", section=s33, role="angle", write=[pitch, sp],
                motion=True, **gimbal),
        command(ident="GAR", name="roll_angle", title="Roll angle", section=s33, role="angle", write=[roll, sp],
                motion=True, **gimbal),
        command(ident="GAM", name="yaw_pitch_angle", title="Yaw and pitch angles", section=s33, role="angle",
                write=[yaw, F("yaw_speed_deg_s", sp.codec, sp.description, 9.9), pitch,
                       F("pitch_speed_deg_s", sp.codec, sp.description, 9.9)],
                motion=True, **gimbal),
        command(ident="GAA", name="attitude_stream", title="Attitude output rate (GAC frames), 0 = off",
                section=f"{DOC} §3.3.2.1", role="attitude_stream",
                write=[F("rate_hz", HexInt(2, max=100, unit="Hz"), "1..100 Hz, 0 = off")], **gimbal),
        command(ident="GAC", name="attitude", title="Attitude (answer and stream)", section=f"{DOC} §3.3.2.2",
                role="attitude", read=attitude_fields(state="attitude"), **gimbal),
        command(ident="SUM", name="tracking_confirm", title="Tracking stop / confirm", section=f"{DOC} §3.3.4",
                role="tracking_confirm", address="G", group="tracking",
                write=[F("action", enum(2, {"00": "stop", "01": "confirm"}))]),
        command(ident="GOT", name="track_target", title="Track the target at a picture position (1280x720)",
                section=f"{DOC} §3.3.5", role="tracking_target", address="G", group="tracking",
                write=[F("x_px", HexInt(4, max=1280, unit="px")), F("y_px", HexInt(4, max=720, unit="px"))]),
        command(ident="FAE", name="vehicle_attitude_enable", title="Vehicle attitude input on / off",
                section=f"{DOC} §3.3.6.1", role="vehicle_attitude_enable", address="G", group="position",
                write=[F("state", on_off)]),
        command(ident="FAI", name="vehicle_attitude", title="Vehicle attitude from the flight controller",
                section=f"{DOC} §3.3.6.2", role="vehicle_attitude", address="G", group="position",
                write=list(attitude_fields("vehicle")),
                extra_forms=write_forms([*attitude_fields("vehicle"), F("flight_mode", FLIGHT_MODE)],
                                        "with flight mode", section=CLIENTS)),
        # -- D class: camera ---------------------------------------------------------------------
        shared.recording_command(f"{DOC} §4.1"),
        command(ident="CAP", name="photo", title="Take a photo", section=f"{DOC} §4.2", role="photo",
                write=[F("mode", enum(2, {"01": "photo"}), default="photo")], repeatable=False, **camera),
        command(ident="VID", name="resolution", title="Recording resolution per lens", section=f"{DOC} §4.3",
                role="resolution",
                write=[F("secondary", LENS_RES, "second visible lens (dual-visible models)", default="null"),
                       F("primary", LENS_RES)],
                read=[F("secondary", LENS_RES), F("primary", LENS_RES, factory="1080p")], **camera),
        command(ident="SDC", name="sd_card", title="SD card capacity", section=f"{DOC} §4.4", role="sd_capacity",
                read=[F("remaining_mb", HexInt(5, unit="MB"), "0 with total 0 = no card", state_key="sd.remaining_mb"),
                      F("total_mb", HexInt(5, unit="MB"), state_key="sd.total_mb")], **camera),
        command(ident="AWB", name="white_balance", title="White balance per lens", section=f"{DOC} §4.5.1",
                role="white_balance",
                write=[F("secondary", AWB, "second visible lens (dual-visible models)", default="null"),
                       F("primary", AWB)],
                read=[F("secondary", AWB), F("primary", AWB)], **camera),
        command(ident="IQE", name="image_params", title="Image style, hue, brightness, saturation, contrast, sharpness",
                section=f"{DOC} §4.5.2", role="image_params", write=_image_params(), read=_image_params(), **camera),
        command(ident="TIM", name="time", title="Date and time", section=f"{DOC} §4.6", role="time", address="D",
                group="position", header="#tp",
                write=[F("time", Timestamp("%H%M%S.%f2%d%m%y"), "hhmmss.ss DDMMYY")]),
        command(ident="DZM", name="digital_zoom", title="Digital zoom 1..4x and steps", section=f"{DOC} §4.7",
                role="digital_zoom", address="D", group="lens",
                write=[F("zoom", DIGITAL_ZOOM)],
                read=[F("zoom", enum(2, {"01": "1x", "02": "2x", "03": "3x", "04": "4x"}), state_key="zoom.digital")],
                extra_forms=shared.digital_zoom_client_forms(two_char=False)),
        shared.palette_command(f"{DOC} §4.8", PALETTES),
        *shared.network_commands({
            "IPV": f"{DOC} §4.9.1", "GTW": f"{DOC} §4.9.2", "DNS": f"{DOC} §4.9 (table)",
            "BNS": f"{DOC} §4.9 (table)", "RST": f"{DOC} Appendix I (TOPOTEK §五.7 layout)",
        }),
        command(ident="RTF", name="reboot", title="Reboot or restore factory settings",
                section=f"{DOC} Appendix I (data layout undocumented)", role="reboot", address="D", group="system",
                write=[F("action", enum(2, {"00": "reboot", "01": ("factory_reset", "Restore factory settings")}))],
                repeatable=False,
                notes="Data layout not documented: 00 reboot, 01 factory reset is our decision (errata E13)."),
        command(ident="VOM", name="video_output", title="Video output parameters", section=f"{DOC} §4.10",
                role="video_output", header="#tp", write=_video_output(), read=_video_output(), **camera),
        command(ident="VER", name="version", title="Software version", section=f"{DOC} §4.11", role="version",
                address="D", group="system",
                read=[F("version", Text(1, 15), "e.g. V1.0.0", state_key="version")]),
        command(ident="EXT", name="extended", title="OSD, LED and dish-effect calibration", section=f"{DOC} §4.12",
                role="osd", header="#tp", write=_extended(True), read=_extended(False), **camera),
        command(ident="UID", name="uid", title="User id (C12, in development)", section=f"{DOC} §4.13", role="uid",
                address="D", group="system", header="#tp",
                write=[F("uid", HexInt(8))], read=[F("uid", HexInt(8))]),
        # -- D class: thermal and range ----------------------------------------------------------
        command(ident="TSM", name="thermal_scene", title="Thermal scene mode", section=f"{DOC} §4.14",
                role="thermal_scene", write=[F("scene", SCENES)], read=[F("scene", SCENES)], **thermal),
        command(ident="TAS", name="thermal_shutter", title="Thermal automatic shutter interval",
                section=f"{DOC} §4.15", role="thermal_shutter",
                write=[F("interval_s", HexInt(2, max=100, unit="s"), "C12: 0..25 (0 = off); C13: 5..100")],
                read=[F("interval_s", HexInt(2, unit="s"), factory=10)], **thermal),
        *(
            command(ident=ident, name=f"thermal_{name}", title=title, section=f"{DOC} §{sect}",
                    role="thermal_setting", write=[level(name)], read=[level(name, factory=50)], **thermal)
            for ident, name, title, sect in (
                ("TDI", "detail", "Thermal detail enhancement", "4.16"),
                ("TIB", "brightness", "Thermal brightness", "4.17"),
                ("TIC", "contrast", "Thermal contrast", "4.18"),
                ("TAR", "spatial_denoise", "Thermal spatial noise reduction", "4.19"),
                ("TTR", "temporal_denoise", "Thermal temporal noise reduction", "4.20"),
                ("TGM", "gamma", "Thermal gamma", "4.21"),
            )
        ),
        command(ident="SLR", name="laser_range", title="Single laser range measurement; range limit",
                section=f"{DOC} §4.22", role="range", address="D", group="range",
                read=[F("distance_m", HexInt(4, scale=0.1, unit="m"), "0.5..100.0 m (5..1000 dm)",
                        state_key="range_m")],
                extra_forms=[
                    *write_forms(
                        [F("limit_m", HexInt(4, scale=0.1, unit="m", min=5.0, max=1000.0),
                           "measurement range limit, decimetres on the wire (0x32..0x2710)")],
                        "range limit", section=CLIENTS),
                    # a public C13 ground station fires one measurement, then reads it (errata E30)
                    *write_forms([F("action", enum(2, {"01": ("measure", "Fire one measurement (read it after)")}))],
                                 "fire", section=f"{CLIENTS} (public C13 ground station)"),
                ]),
        # -- Appendix I only ---------------------------------------------------------------------
        *shared.lens_commands({"ZMC": APPENDIX, "FCC": APPENDIX, "ZFP": APPENDIX, "IRC": APPENDIX}),
        *shared.position_commands({"LAT": APPENDIX, "LON": APPENDIX, "ALT": APPENDIX}, target=False),
        command(ident="MNU", name="menu", title="Menu (layout not documented)", section=f"{DOC} Appendix I",
                role="menu", address="D", group="system", write=raw),
        command(ident="EVS", name="exposure_compensation", title="Exposure compensation (layout not documented)",
                section=f"{DOC} Appendix I", role="exposure", write=raw,
                read=[F("data", RawData(None, max_bytes=15), "layout not documented", factory="00")], **camera),
        command(ident="TMP", name="temperature", title="Temperature (layout not documented)",
                section=f"{DOC} Appendix I", role="temperature", extra_forms=[report(*raw)], read=raw, **thermal),
        # -- beyond the document: what public clients ask -----------------------------------------
        command(ident="HWV", name="hardware_version", title="Hardware version", section=CLIENTS,
                role="hardware_version", address="D", group="system", documented=False,
                read=[F("hardware_version", Text(1, 15), state_key="hardware_version")]),
        command(ident="MOD", name="model_name", title="Model name (C11, C13...)", section=CLIENTS,
                role="model_name", address="D", group="system", documented=False,
                read=[F("model", Text(1, 15), "e.g. C11", state_key="model_name")],
                notes="Some C12 firmware answers minutes late or never: never block on it (the profile's "
                "slow_answers)."),
    ]  # fmt: skip


def skydroid(*, speed_unit_deg_s: float = 0.1, destinations: Mapping[str, str] | None = None) -> Dialect:
    """Build the SkyDroid dialect.

    speed_unit_deg_s: GS* step; the text and its worked example say 0.1 deg/s, the table 0.5 deg/s
    (errata E7). Pass 0.5 for firmware that follows the table (the C11 profile does).
    destinations: {ident: address} for firmware that wants a command elsewhere (C11 DZM to M).
    A profile's max_rate_deg_s follows its speed unit (127 steps) unless the profile fixes the unit.
    """
    return shared.build_dialect(
        "skydroid",
        TITLE,
        commands(speed_unit_deg_s),
        MODELS,
        max_rate_deg_s=round(RATE_STEPS * speed_unit_deg_s, 6),
        options={"speed_unit_deg_s": speed_unit_deg_s},
        destinations=destinations,
        host_addresses="U",
        headers=("#TP", "#tp"),
        gimbal_header="#TP",
    )


__all__ = ["DOC", "TITLE", "commands", "skydroid"]
