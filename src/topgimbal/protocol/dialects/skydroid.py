"""SkyDroid "TOP 协议" V1.1.5 (C10, C10Pro, C12, C13, C20).

Model support comes from each section's 支持 line; a section without one applies to every model.
Commands the document names only in Appendix I take TOPOTEK's layout (errata E12).
"""

from __future__ import annotations

from dataclasses import replace
from typing import Any

from ..catalog import CommandSpec, DeviceModel, Dialect, Endpoint
from ..fields import Field, HexInt, RawData, Text, Timestamp, enum
from ._build import F, angle, attitude_fields, level, report, spec
from ._shared import error_frame, lens_commands, network_commands, on_off_codec, position_commands

DOC = "SkyDroid"
# Commands that move the gimbal (some firmware obeys them without an echo).
MOTION = frozenset(["PTZ", "GSY", "GSP", "GSR", "GSM", "GAY", "GAP", "GAR", "GAM"])
APPENDIX = f"{DOC} Appendix I (layout not given; TOPOTEK's assumed)"

GIMBAL = frozenset({"C10", "C10Pro", "C12", "C20"})
CAMERA = frozenset({"C10", "C10Pro", "C12"})
C12 = frozenset({"C12"})
C13 = frozenset({"C13"})

PTZ = enum(
    2,
    {
        "00": "stop",
        "01": ("up", "Nudge up"),
        "02": ("down", "Nudge down"),
        "03": ("left", "Nudge left"),
        "04": ("right", "Nudge right"),
        "05": ("center", "Centre (回中)"),
        "06": ("follow", "Follow (跟随)"),
        "07": ("lock", "Lock heading (锁头)"),
        "08": ("toggle_follow_lock", "Toggle follow / lock"),
        "09": ("calibrate", "Gimbal calibration"),
        "0A": ("mount_hanging", "Hanging (under-slung) mount 吊装"),
        "0B": ("mount_inverted", "Inverted (upright) mount 倒装"),
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
    toggles=("01", "02", "03", "04", "08", "09", "0C", "0D", "0E", "0F", "10", "11", "12", "13"),
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
        "01": ("white_hot", "White hot 白热"),
        "03": ("sepia", "Sepia 辉金"),
        "04": ("ironbow", "Ironbow 铁红"),
        "05": ("rainbow", "Rainbow 彩虹"),
        "06": ("night", "Night 微光"),
        "07": ("aurora", "Aurora 极光"),
        "08": ("red_hot", "Red hot 红热"),
        "09": ("jungle", "Jungle 丛林"),
        "0A": ("medical", "Medical 医疗"),
        "0B": ("black_hot", "Black hot 黑热"),
        "0C": ("glory_hot", "Glory hot 金红"),
    },
)
SCENES = enum(
    2,
    {
        "00": ("general", "General 通用"),
        "03": ("low_temp_highlight", "Low-temperature highlight 低温突出"),
        "04": ("linear_stretch", "Linear stretch 线性拉伸"),
        "05": ("low_contrast", "Low contrast 低对比度"),
        "06": ("high_contrast", "High contrast 高对比度"),
        "07": ("highlight", "Highlight 高亮突出"),
    },
)
BIT1 = enum(1, {"0": "off", "1": "on"})


def _speed(axis: str, unit: float) -> Field:
    return F(
        f"{axis}_rate_deg_s",
        HexInt(2, signed=True, scale=unit, unit="deg/s", min=-127 * unit, max=127 * unit),
        f"{axis} rate, -127..127 steps; right / up positive",
        axis=axis,
    )


def skydroid(*, speed_unit_deg_s: float = 0.1) -> Dialect:
    """Build the SkyDroid dialect.

    speed_unit_deg_s: GS* step; the text and its worked example say 0.1 deg/s, the table 0.5 deg/s
    (errata E6). Pass 0.5 for firmware that follows the table.
    """
    u = speed_unit_deg_s
    on_off = on_off_codec()
    sp = F("speed_deg_s", HexInt(2, scale=0.1, unit="deg/s", max=9.9), "slew speed 0..99 x 0.1 deg/s", default=9.9)
    yaw = angle("yaw_deg", -90, 90, "yaw, right-positive")
    pitch = angle("pitch_deg", -90, 90, "pitch, up-positive")
    roll = angle("roll_deg", -90, 90, "roll (struck out in V1.0.7: not supported for now)")
    s33 = f"{DOC} §3.3.1"
    cmds: list[CommandSpec] = [error_frame(f"{DOC} §2.3.2")]
    cmds += [
        spec(
            "PTZ", "gimbal_control", "Gimbal control codes", "G", f"{DOC} §3.1", write=[F("action", PTZ)], models=GIMBAL
        ),
        spec("GSY", "yaw_rate", "Yaw speed", "G", f"{DOC} §3.2", write=[_speed("yaw", u)], models=GIMBAL),
        spec("GSP", "pitch_rate", "Pitch speed", "G", f"{DOC} §3.2", write=[_speed("pitch", u)], models=GIMBAL),
        spec("GSR", "roll_rate", "Roll speed", "G", f"{DOC} §3.2", write=[_speed("roll", u)], models=GIMBAL),
        spec(
            "GSM",
            "yaw_pitch_rate",
            "Yaw and pitch speed",
            "G",
            f"{DOC} §3.2",
            write=[_speed("yaw", u), _speed("pitch", u)],
            models=GIMBAL,
        ),
        spec("GAY", "yaw_angle", "Yaw angle", "G", s33, write=[yaw, sp], models=GIMBAL),
        spec("GAP", "pitch_angle", "Pitch angle", "G", s33, write=[pitch, sp], models=GIMBAL),
        spec("GAR", "roll_angle", "Roll angle", "G", s33, write=[roll, sp], models=GIMBAL),
        spec(
            "GAM",
            "yaw_pitch_angle",
            "Yaw and pitch angles",
            "G",
            s33,
            write=[
                yaw,
                F("yaw_speed_deg_s", sp.codec, sp.description, 9.9),
                pitch,
                F("pitch_speed_deg_s", sp.codec, sp.description, 9.9),
            ],
            models=GIMBAL,
        ),
        spec(
            "GAA",
            "attitude_stream",
            "Attitude output rate (GAC frames), 0 = off",
            "G",
            f"{DOC} §3.3.2.1",
            write=[F("rate_hz", HexInt(2, max=100, unit="Hz"), "1..100 Hz, 0 = off")],
            models=GIMBAL,
        ),
        spec(
            "GAC",
            "attitude",
            "Attitude (answer and stream)",
            "G",
            f"{DOC} §3.3.2.2",
            read=attitude_fields(),
            models=GIMBAL,
        ),
        spec(
            "SUM",
            "tracking_confirm",
            "Tracking stop / confirm",
            "G",
            f"{DOC} §3.3.4",
            write=[F("action", enum(2, {"00": "stop", "01": "confirm"}))],
            models=C12,
        ),
        spec(
            "GOT",
            "track_target",
            "Track the target at a picture position (1280x720)",
            "G",
            f"{DOC} §3.3.5",
            write=[F("x_px", HexInt(4, max=1280, unit="px")), F("y_px", HexInt(4, max=720, unit="px"))],
            models=C12,
        ),
        spec(
            "FAE",
            "vehicle_attitude_enable",
            "Vehicle attitude input on / off",
            "G",
            f"{DOC} §3.3.6.1",
            write=[F("state", on_off)],
            models=C12,
        ),
        spec(
            "FAI",
            "vehicle_attitude",
            "Vehicle attitude from the flight controller",
            "G",
            f"{DOC} §3.3.6.2",
            write=list(attitude_fields("vehicle")),
            models=C12,
        ),
    ]
    rec = enum(2, {"00": "stop", "01": "start", "0A": ("toggle", "Toggle")}, toggles="0A")
    cmds += [
        spec(
            "REC",
            "recording",
            "Start / stop / toggle recording; query state",
            "D",
            f"{DOC} §4.1",
            write=[F("action", rec)],
            read=[F("state", enum(2, {"00": ("stopped", "Not recording"), "01": ("recording", "Recording")}))],
            models=CAMERA,
        ),
        spec(
            "CAP",
            "photo",
            "Take a photo",
            "D",
            f"{DOC} §4.2",
            write=[F("mode", enum(2, {"01": "photo"}), default="photo")],
            models=CAMERA,
            repeatable=False,
        ),
        spec(
            "VID",
            "resolution",
            "Recording resolution per lens",
            "D",
            f"{DOC} §4.3",
            write=[
                F("secondary", LENS_RES, "second visible lens (dual-visible models)", default="null"),
                F("primary", LENS_RES),
            ],
            read=[F("secondary", LENS_RES), F("primary", LENS_RES)],
            models=C12,
        ),
        spec(
            "SDC",
            "sd_card",
            "SD card capacity",
            "D",
            f"{DOC} §4.4",
            read=[
                F("remaining_mb", HexInt(5, unit="MB"), "0 with total 0 = no card"),
                F("total_mb", HexInt(5, unit="MB")),
            ],
            models=C12,
        ),
        spec(
            "AWB",
            "white_balance",
            "White balance per lens",
            "D",
            f"{DOC} §4.5.1",
            write=[F("secondary", AWB, "second visible lens (dual-visible models)", default="null"), F("primary", AWB)],
            read=[F("secondary", AWB), F("primary", AWB)],
        ),
        spec(
            "IQE",
            "image_params",
            "Image style, hue, brightness, saturation, contrast, sharpness",
            "D",
            f"{DOC} §4.5.2",
            write=[
                F("lens", HexInt(1), "lens id", default=0),
                F("style", enum(1, {"0": "custom", "1": "standard", "2": "bright", "3": "vivid"})),
                level("hue", 255),
                level("brightness", 255),
                level("saturation", 255),
                level("contrast", 255),
                level("sharpness", 255),
            ],
            read=[
                F("lens", HexInt(1)),
                F("style", enum(1, {"0": "custom", "1": "standard", "2": "bright", "3": "vivid"})),
                level("hue", 255),
                level("brightness", 255),
                level("saturation", 255),
                level("contrast", 255),
                level("sharpness", 255),
            ],
            models=C12,
        ),
        spec(
            "TIM",
            "time",
            "Date and time",
            "D",
            f"{DOC} §4.6",
            header="#tp",
            write=[F("time", Timestamp("%H%M%S.%f2%d%m%y"), "hhmmss.ss DDMMYY")],
            models=CAMERA,
        ),
        spec(
            "DZM",
            "digital_zoom",
            "Digital zoom 1..4x and steps",
            "D",
            f"{DOC} §4.7",
            write=[
                F(
                    "zoom",
                    enum(
                        2,
                        {
                            "01": "1x",
                            "02": "2x",
                            "03": "3x",
                            "04": "4x",
                            "0A": ("zoom_in", "Zoom +"),
                            "0B": ("zoom_out", "Zoom -"),
                        },
                        toggles=("0A", "0B"),
                    ),
                )
            ],
            read=[F("zoom", enum(2, {"01": "1x", "02": "2x", "03": "3x", "04": "4x"}))],
            models=C12,
        ),
        spec(
            "IMG",
            "palette",
            "Thermal palette",
            "D",
            f"{DOC} §4.8",
            write=[F("palette", PALETTES)],
            read=[F("palette", PALETTES)],
            models=C12,
        ),
    ]
    cmds += network_commands(
        {
            "IPV": f"{DOC} §4.9.1",
            "GTW": f"{DOC} §4.9.2",
            "DNS": f"{DOC} §4.9 (table)",
            "BNS": f"{DOC} §4.9 (table)",
            "RST": f"{DOC} Appendix I (TOPOTEK §五.7 layout)",
        }
    )
    vom = [
        F("h_flip", BIT1),
        F("v_flip", BIT1),
        F("fps", HexInt(2, min=1, max=60, unit="fps")),
        F("gop", HexInt(2, min=1, max=255, unit="frames"), "frames between key frames"),
        F("bitrate_kbps", HexInt(4, min=100, max=10240, unit="kbps")),
        F("output", BIT1, "video data output"),
    ]
    cmds += [
        spec(
            "RTF",
            "reboot",
            "Reboot or restore factory settings",
            "D",
            f"{DOC} Appendix I (data layout undocumented)",
            write=[F("action", enum(2, {"00": "reboot", "01": ("factory_reset", "Restore factory settings")}))],
            repeatable=False,
            notes="Data layout not documented: 00 reboot, 01 factory reset is our decision (errata E13).",
        ),
        spec(
            "VOM",
            "video_output",
            "Video output parameters",
            "D",
            f"{DOC} §4.10",
            header="#tp",
            write=vom,
            read=vom,
            models=CAMERA,
        ),
        spec(
            "VER",
            "version",
            "Software version",
            "D",
            f"{DOC} §4.11",
            read=[F("version", Text(1, 15), "e.g. V1.0.0")],
            models=CAMERA,
        ),
        spec(
            "EXT",
            "extended",
            "OSD, LED and dish-effect calibration",
            "D",
            f"{DOC} §4.12",
            header="#tp",
            write=[
                F("reserved", enum(1, {"0": "zero"}), default="zero"),
                F("dish_calibration", BIT1, default="off"),
                F("osd", BIT1),
                F("led", BIT1),
            ],
            read=[F("reserved", enum(1, {"0": "zero"})), F("dish_calibration", BIT1), F("osd", BIT1), F("led", BIT1)],
            models=frozenset({"C10Pro", "C12"}),
        ),
        spec(
            "UID",
            "uid",
            "User id (C12, in development)",
            "D",
            f"{DOC} §4.13",
            header="#tp",
            write=[F("uid", HexInt(8))],
            read=[F("uid", HexInt(8))],
            models=C12,
        ),
        spec(
            "TSM",
            "thermal_scene",
            "Thermal scene mode",
            "D",
            f"{DOC} §4.14",
            write=[F("scene", SCENES)],
            read=[F("scene", SCENES)],
            models=C13,
        ),
        spec(
            "TAS",
            "thermal_shutter",
            "Thermal automatic shutter interval",
            "D",
            f"{DOC} §4.15",
            write=[F("interval_s", HexInt(2, max=100, unit="s"), "C12: 0..25 (0 = off); C13: 5..100")],
            read=[F("interval_s", HexInt(2, unit="s"))],
            models=frozenset({"C12", "C13"}),
        ),
    ]
    for ident, name, title, sect in (
        ("TDI", "detail", "Thermal detail enhancement", "4.16"),
        ("TIB", "brightness", "Thermal brightness", "4.17"),
        ("TIC", "contrast", "Thermal contrast", "4.18"),
        ("TAR", "spatial_denoise", "Thermal spatial noise reduction", "4.19"),
        ("TTR", "temporal_denoise", "Thermal temporal noise reduction", "4.20"),
        ("TGM", "gamma", "Thermal gamma", "4.21"),
    ):
        cmds.append(
            spec(
                ident,
                f"thermal_{name}",
                title,
                "D",
                f"{DOC} §{sect}",
                write=[level(name)],
                read=[level(name)],
                models=C13,
            )
        )
    cmds += [
        spec(
            "SLR",
            "laser_range",
            "Single laser range measurement",
            "D",
            f"{DOC} §4.22",
            read=[F("distance_m", HexInt(4, scale=0.1, unit="m"), "0.5..100.0 m (5..1000 dm)")],
            models=C13,
        ),
    ]
    # Named in Appendix I only.
    cmds += lens_commands({"ZMC": APPENDIX, "FCC": APPENDIX, "ZFP": APPENDIX, "IRC": APPENDIX})
    cmds += position_commands({"LAT": APPENDIX, "LON": APPENDIX, "ALT": APPENDIX}, target=False)
    raw = [F("data", RawData(None), "layout not documented")]
    cmds += [
        spec("MNU", "menu", "Menu (layout not documented)", "D", f"{DOC} Appendix I", write=raw),
        spec(
            "EVS",
            "exposure_compensation",
            "Exposure compensation (layout not documented)",
            "D",
            f"{DOC} Appendix I",
            write=raw,
            read=raw,
        ),
        spec(
            "TMP",
            "temperature",
            "Temperature (layout not documented)",
            "D",
            f"{DOC} Appendix I",
            extra_forms=[report(*raw)],
            read=raw,
        ),
    ]

    def m(name: str, title: str, endpoints: tuple[Endpoint, ...], **kw: Any) -> DeviceModel:
        return DeviceModel(
            name,
            "skydroid",
            title,
            endpoints,
            yaw_range_deg=(-90.0, 90.0),
            pitch_range_deg=(-90.0, 90.0),
            roll_range_deg=(-90.0, 90.0),
            max_rate_deg_s=12.7 if u <= 0.1 else 127 * u,
            **kw,
        )

    udp = (Endpoint("udp", 5000),)
    models = [
        m(
            "C10",
            "SkyDroid C10",
            (Endpoint("udp", 5000), Endpoint("tcp", 5000), Endpoint("udp", 9002)),
            optical_zoom_max=10.0,
        ),
        m("C10Pro", "SkyDroid C10 Pro", udp, optical_zoom_max=10.0),
        m(
            "C12",
            "SkyDroid C12 (visible + thermal)",
            udp,
            thermal=True,
            digital_zoom_max=4.0,
            limits={("TAS", "interval_s"): (0.0, 25.0)},
        ),
        m(
            "C13",
            "SkyDroid C13 (thermal + laser range)",
            udp,
            thermal=True,
            lrf_range_m=(0.5, 100.0),
            limits={("TAS", "interval_s"): (5.0, 100.0)},
        ),
        m("C20", "SkyDroid C20", (Endpoint("tcp", 5000),)),
    ]
    cmds = [replace(c, motion=True) if c.ident in MOTION else c for c in cmds]
    return Dialect(
        "skydroid",
        'SkyDroid "TOP 协议" V1.1.5',
        cmds,
        models,
        host_addresses="U",
        headers=("#TP", "#tp"),
        gimbal_header="#TP",
        options={"speed_unit_deg_s": speed_unit_deg_s},
    )
