"""TOPOTEK "Udp&uart-Protocol" V1.1.3 (SIP series), plus what real clients send beyond it.

Sections cite the document's numbering (三 = M class, 四 = G class, 五 = D class). Values are as
on the wire: no sign changes here (the client maps its one convention to each dialect's signs).
"""

from __future__ import annotations

from dataclasses import replace

from ..catalog import REQUEST, CommandSpec, DeviceModel, Dialect, Endpoint, Form
from ..fields import (
    BinInt,
    Bitrate,
    DecFloat,
    DecInt,
    Field,
    HexInt,
    OneOf,
    RawData,
    Text,
    Timestamp,
    enum,
)
from ._build import F, angle, attitude_fields, report, request, spec
from ._shared import error_frame, lens_commands, network_commands, on_off_codec, position_commands

DOC = "TOPOTEK"
# Commands that move the gimbal (some firmware obeys them without an echo).
MOTION = frozenset(
    ["PTZ", "GSY", "GSP", "GSR", "GSM", "RPS", "YPR", "GAY", "GAP", "GAR", "GAM", "GIY", "GIP", "GIR", "GIM"]
)
BEYOND = "beyond the documents (real clients)"

PTZ = enum(
    2,
    {
        "00": "stop",
        "01": ("up", "Nudge up"),
        "02": ("down", "Nudge down"),
        "03": ("left", "Nudge left"),
        "04": ("right", "Nudge right"),
        "05": ("center", "Centre (回中)"),
        "06": ("lock", "Lock heading (锁头)"),
        "07": ("follow", "Follow (跟随)"),
        "08": ("toggle_follow_lock", "Toggle follow / lock"),
        "09": ("calibrate", "Gimbal calibration"),
        "0A": ("look_down", "One-key look down (一键向下)"),
    },
    toggles=("01", "02", "03", "04", "08", "09"),
)

PALETTES = enum(
    2,
    {
        "00": ("white_hot", "White hot 白热"),
        "01": ("lava", "Lava 熔岩"),
        "02": ("ironbow", "Ironbow 铁红"),
        "03": ("hot_iron", "Hot iron 热铁"),
        "04": ("medical", "Medical 医疗"),
        "05": ("arctic", "Arctic 北极"),
        "06": ("rainbow1", "Rainbow 1 彩虹1"),
        "07": ("rainbow2", "Rainbow 2 彩虹2"),
        "08": ("red_tint", "Red tint 描红"),
        "09": ("black_hot", "Black hot 黑热"),
        "0A": ("next", "Next palette"),
        "0B": ("previous", "Previous palette"),
    },
    toggles=("0A", "0B"),
)

PIP_MODE = enum(
    1,
    {
        "0": ("main_only", "Main only"),
        "1": ("main_sub", "Main + sub"),
        "2": ("sub_main", "Sub + main"),
        "3": ("sub_only", "Sub only"),
        "A": ("next", "Next layout"),
        "B": ("previous", "Previous layout"),
    },
    toggles=("A", "B"),
)

REC_STATE = enum(2, {"00": ("stopped", "Not recording"), "01": ("recording", "Recording")})
REC_FEEDBACK = enum(2, {"00": ("stopped", "Recording stopped"), "11": ("started", "Recording started")})
FILE_INDEX = HexInt(8)


def _speed(axis: str, unit: float) -> Field:
    return F(
        f"{axis}_rate_deg_s",
        HexInt(2, signed=True, scale=unit, unit="deg/s", min=-99 * unit, max=99 * unit),
        f"{axis} rate, -99..99 steps" + ("; pitch down-positive on the wire (§四.2)" if axis == "pitch" else ""),
        axis=axis,
    )


def _angle_cmds(prefix: str, frame: str, section: str, name_prefix: str) -> list[CommandSpec]:
    sp = F("speed_deg_s", HexInt(2, scale=0.1, unit="deg/s", max=9.9), "slew speed 0..99 x 0.1 deg/s", default=9.9)
    yaw = angle("yaw_deg", -150, 150, f"yaw ({frame}), right-positive")
    pitch = angle(
        "pitch_deg", -90, 90, f"pitch ({frame}); the document says up-positive, ArduPilot finds down-positive"
    )
    roll = angle("roll_deg", -90, 90, f"roll ({frame})")
    ys = F("yaw_speed_deg_s", sp.codec, sp.description, default=9.9)
    ps = F("pitch_speed_deg_s", sp.codec, sp.description, default=9.9)
    return [
        spec(f"{prefix}Y", f"{name_prefix}yaw_angle", f"Yaw angle, {frame}", "G", write=[yaw, sp], section=section),
        spec(
            f"{prefix}P", f"{name_prefix}pitch_angle", f"Pitch angle, {frame}", "G", write=[pitch, sp], section=section
        ),
        spec(f"{prefix}R", f"{name_prefix}roll_angle", f"Roll angle, {frame}", "G", write=[roll, sp], section=section),
        spec(
            f"{prefix}M",
            f"{name_prefix}yaw_pitch_angle",
            f"Yaw and pitch angles, {frame}",
            "G",
            write=[yaw, ys, pitch, ps],
            section=section,
        ),
    ]


def topotek(*, speed_unit_deg_s: float = 1.0, binary_byteorder: str = "little") -> Dialect:
    """Build the TOPOTEK dialect.

    speed_unit_deg_s: GS*/RPS/YPR step. The table says deg/s, the text 0.1 deg/s (errata E7);
    binary_byteorder: GPS/UAV struct byte order, which the document does not state (errata E9).
    """
    u = speed_unit_deg_s
    bo = binary_byteorder
    on_off = on_off_codec()
    cmds: list[CommandSpec] = [error_frame(f"{DOC} §二 (response mechanism, as SkyDroid §2.3.2)")]

    # -- M class: lens -------------------------------------------------------------------------
    cmds += lens_commands(
        {"ZMC": f"{DOC} §三.1.1", "FCC": f"{DOC} §三.2.1", "ZFP": f"{DOC} §三.3", "IRC": f"{DOC} §三.6"}
    )
    pos = F("zoom_pos", HexInt(4, signed=True), "zoom motor position")
    cmds += [
        spec("ZOM", "zoom_position", "Read the zoom position", "M", f"{DOC} §三.1.2", read=[pos]),
        spec(
            "FOC",
            "focus_position",
            "Read the focus position",
            "M",
            f"{DOC} §三.2.2",
            read=[F("focus_pos", HexInt(4, signed=True), "focus motor position")],
        ),
        spec(
            "ZMP",
            "zoom_report",
            "Magnification and zoom position, sent after each zoom change",
            "M",
            f"{DOC} §三.4",
            extra_forms=[
                report(F("magnification_x", DecInt(3, scale=0.1, unit="x"), "optical magnification"), pos, rw="r")
            ],
        ),
        spec(
            "SWH",
            "aux_power",
            "Power an auxiliary device (not yet supported by the device)",
            "M",
            f"{DOC} §三.5",
            write=[
                F(
                    "device",
                    enum(
                        1,
                        {
                            "5": ("rangefinder_5v", "5 V: rangefinder / dust sensor"),
                            "C": ("light_12v", "12 V: fill light"),
                        },
                    ),
                ),
                F("state", enum(1, {"0": "off", "1": "on"})),
            ],
            read=[
                F("device", enum(1, {"5": "rangefinder_5v", "C": "light_12v"})),
                F("state", enum(1, {"0": "off", "1": "on"})),
            ],
        ),
        spec("ATE", "ate_mode", "ATE (factory test) mode", "M", f"{DOC} §三.7", write=[F("state", on_off)]),
        spec(
            "VSN",
            "version",
            "Firmware version",
            "D",
            f"{DOC} §三.8 (lens, M) and §五.16 (system, D)",
            read=[F("version", Text(1, 15), "version text, e.g. M3326 (lens) or two characters (system)")],
            addresses=("M",),
        ),
        spec(
            "MUL",
            "magnification",
            "Optical magnification",
            "M",
            f"{DOC} §三.9",
            write=[F("magnification_x", DecInt(4, scale=0.1, unit="x", min=1.0))],
            read=[F("magnification_x", DecInt(4, scale=0.1, unit="x"))],
        ),
        spec(
            "APC",
            "aperture_control",
            "Aperture: - / + / stop",
            "M",
            f"{DOC} §三.10",
            write=[F("action", enum(2, {"00": "stop", "01": ("close", "Aperture -"), "02": ("open", "Aperture +")}))],
        ),
        spec(
            "LRF",
            "rangefinder",
            "Laser rangefinder: control (to M) and distance results (from the device)",
            "M",
            f"{DOC} §五.9",
            write=[
                F(
                    "action",
                    enum(
                        2,
                        {
                            "00": "stop",
                            "01": ("on", "Rangefinder on"),
                            "02": ("single", "Single measurement"),
                            "03": ("continuous", "Continuous measurement (00 stops)"),
                        },
                        toggles="02",
                    ),
                )
            ],
            extra_forms=[
                report(
                    F(
                        "distance_m",
                        DecFloat(None, 1, "m", 0, 99999.9, none_tokens=(b"ERR",), pad=7),
                        "distance, or null when the measurement failed (ERR)",
                    ),
                    title="result",
                )
            ],
            notes="Result: X1X2X3X4X5.X6 metres; ERR = failed (too near or too far).",
        ),
    ]

    # -- G class: gimbal -----------------------------------------------------------------------
    cmds += [
        spec("PTZ", "gimbal_control", "Gimbal control codes", "G", f"{DOC} §四.1", write=[F("action", PTZ)]),
        spec("GSY", "yaw_rate", "Yaw speed", "G", f"{DOC} §四.2", write=[_speed("yaw", u)]),
        spec("GSP", "pitch_rate", "Pitch speed", "G", f"{DOC} §四.2", write=[_speed("pitch", u)]),
        spec("GSR", "roll_rate", "Roll speed", "G", f"{DOC} §四.2", write=[_speed("roll", u)]),
        spec(
            "GSM",
            "yaw_pitch_rate",
            "Yaw and pitch speed",
            "G",
            f"{DOC} §四.2",
            write=[_speed("yaw", u), _speed("pitch", u)],
            header="#tp",
        ),
        spec(
            "RPS",
            "roll_pitch_rate",
            "Roll and pitch speed",
            "G",
            f"{DOC} §四.2",
            write=[_speed("roll", u), _speed("pitch", u)],
            header="#tp",
        ),
        spec(
            "YPR",
            "yaw_pitch_roll_rate",
            "Yaw, pitch and roll speed",
            "G",
            f"{DOC} §四.2",
            write=[_speed("yaw", u), _speed("pitch", u), _speed("roll", u)],
            header="#tp",
        ),
    ]
    cmds += _angle_cmds("GA", "body frame", f"{DOC} §四.3.1 (magnetic encoder)", "")
    cmds += _angle_cmds("GI", "earth frame", f"{DOC} §四.3.2 (gyro)", "earth_")
    att = attitude_fields()
    cmds += [
        spec("GAC", "attitude", "Read the attitude (magnetic encoder, body frame)", "G", f"{DOC} §四.3.3", read=att),
        spec(
            "GAA",
            "attitude_stream",
            "Attitude output on / off (GAC frames)",
            "G",
            f"{DOC} §四.3.4",
            write=[F("state", on_off)],
            read=[F("state", on_off)],
        ),
        spec("GIC", "gyro_attitude", "Read the attitude (gyro, earth frame)", "G", f"{DOC} §四.3.5", read=att),
        spec(
            "GIA",
            "gyro_attitude_stream",
            "Gyro attitude output on / off; the stream itself",
            "G",
            f"{DOC} §四.3.6",
            write=[F("state", on_off)],
            read=[F("state", on_off)],
            extra_forms=[
                report(*att, rw="r", title="stream (first 12 characters; ArduPilot)"),
                report(
                    *att,
                    F("extra", RawData(None), "characters after the first 12"),
                    rw="r",
                    title="stream with extra data",
                ),
                report(*att, title="stream (w)"),
            ],
        ),
        spec(
            "GMS",
            "motors",
            "Gimbal motors on / off",
            "G",
            f"{DOC} §四.4",
            write=[F("state", on_off)],
            read=[F("state", on_off)],
        ),
        spec(
            "VER",
            "serial_number",
            "Serial number (some models)",
            "G",
            f"{DOC} §四.5",
            read=[F("serial", Text(1, 15), "14 characters")],
        ),
    ]

    # -- D class: system and image -------------------------------------------------------------
    photo_mode = enum(
        2,
        {
            "01": ("visible_thermal", "Visible + thermal"),
            "02": ("visible", "Visible only"),
            "03": ("thermal", "Thermal only"),
            "05": ("radiometric", "Visible, thermal and radiometric file"),
        },
    )
    cmds += [
        spec(
            "REC",
            "recording",
            "Start / stop / toggle recording; query state",
            "D",
            f"{DOC} §五.1",
            write=[F("action", enum(2, {"00": "stop", "01": "start", "0A": ("toggle", "Toggle")}, toggles="0A"))],
            read=[F("state", REC_STATE)],
            extra_forms=[
                report(
                    F("state", REC_FEEDBACK),
                    F("file_index", FILE_INDEX, "stream_0_<idx>.h264"),
                    title="feedback with file index",
                )
            ],
        ),
        spec(
            "CAP",
            "photo",
            "Take a photo",
            "D",
            f"{DOC} §五.2",
            write=[F("mode", photo_mode, default="visible_thermal")],
            repeatable=False,
            extra_forms=[
                report(
                    F("state", enum(2, {"11": ("taken", "Photo taken")})),
                    F("file_index", FILE_INDEX, "snap_0_<idx>.jpeg"),
                    title="feedback with file index",
                )
            ],
        ),
        spec(
            "VID",
            "resolution",
            "Resolution of a stream",
            "D",
            f"{DOC} §五.3",
            write=[
                F("stream", enum(1, {"0": ("record", "Recording"), "1": ("photo", "Photo"), "2": ("rtsp", "RTSP")})),
                F("resolution", enum(1, {"0": "3840x2160", "1": "1920x1080", "2": "1280x720", "3": "640x480"})),
            ],
            read=[
                F("stream", enum(1, {"0": "record", "1": "photo", "2": "rtsp"})),
                F("resolution", enum(1, {"0": "3840x2160", "1": "1920x1080", "2": "1280x720", "3": "640x480"})),
            ],
        ),
        spec(
            "BIT",
            "bitrate",
            "RTSP stream=0 bitrate",
            "D",
            f"{DOC} §五.4",
            write=[F("bitrate_kbps", Bitrate())],
            read=[F("bitrate_kbps", Bitrate())],
        ),
        spec(
            "SDC",
            "sd_card",
            "SD card capacity (remaining or total)",
            "D",
            f"{DOC} §五.5",
            read=[F("capacity_mb", HexInt(5, unit="MB", none_tokens=(b"NNNNN",)), "null = no card")],
            read_request=Form(
                "r",
                REQUEST,
                (F("which", enum(2, {"00": "remaining", "01": "total"}), default="remaining"),),
                title="query",
            ),
        ),
        spec(
            "ROT",
            "rotation",
            "Image flip / mirror",
            "D",
            f"{DOC} §五.6",
            write=[F("rotation", enum(2, {"00": ("normal", "0°"), "02": ("rotate_180", "180°")}))],
            read=[F("rotation", enum(2, {"00": "normal", "02": "rotate_180"}))],
        ),
    ]
    cmds += network_commands({"IPV": f"{DOC} §五.7", "GTW": f"{DOC} §五.7", "RST": f"{DOC} §五.7"}, dns=False)
    cmds += position_commands(
        {"LAT": f"{DOC} §五.8.2, §五.8.7", "LON": f"{DOC} §五.8.1, §五.8.7", "ALT": f"{DOC} §五.8.3"}
    )
    cmds += [
        spec(
            "AZI",
            "azimuth",
            "Vehicle ground course (true north)",
            "D",
            f"{DOC} §五.8.4",
            write=[F("azimuth_deg", DecFloat(None, 1, "deg", 0, 359.9, pad=5))],
        ),
        spec(
            "GPS",
            "gps",
            "Vehicle position (packed binary, sTPGpsInfo)",
            "D",
            f"{DOC} §五.8.5",
            header="#tp",
            write=[
                F(
                    "heading_deg",
                    BinInt(2, True, bo, 0.01, "deg"),
                    "vehicle heading (unit not stated; 0.01 deg assumed)",
                ),
                F("lon_deg", BinInt(4, True, bo, 1e-7, "deg", -180, 180)),
                F("lat_deg", BinInt(4, True, bo, 1e-7, "deg", -90, 90)),
                F("alt_m", BinInt(4, True, bo, 0.001, "m", -500, 10000)),
            ],
        ),
        spec(
            "UAV",
            "vehicle_attitude",
            "Vehicle attitude (packed binary, sTPUavInfo)",
            "D",
            f"{DOC} §五.8.6",
            header="#tp",
            write=[
                F("yaw_deg", BinInt(2, False, bo, 0.01, "deg", 0, 360), "declared int16 but 0..36000: sent unsigned"),
                F("pitch_deg", BinInt(2, True, bo, 0.01, "deg", -90, 90), "down-positive (struct comment)", sign=-1),
                F("roll_deg", BinInt(2, True, bo, 0.01, "deg", -90, 90), "right-positive"),
                F("speed_m_s", BinInt(2, False, bo, 0.01, "m/s", 0, 200)),
                F("path_angle_deg", BinInt(2, False, bo, 0.01, "deg", 0, 360)),
            ],
        ),
        spec("TIM", "time", "Local (Beijing) time", "D", f"{DOC} §五.10", write=[F("time", Timestamp("%Y%m%d%H%M%S"))]),
        spec("UTC", "utc_time", "UTC time", "D", f"{DOC} §五.10", write=[F("time", Timestamp("%H%M%S%d%m%y"))]),
        spec(
            "PIP",
            "picture_in_picture",
            "Picture-in-picture layout",
            "D",
            f"{DOC} §五.11",
            write=[
                F("secondary", PIP_MODE, "second visible lens (dual-visible models)", default="main_only"),
                F("mode", PIP_MODE),
            ],
            read=[F("secondary", PIP_MODE), F("mode", PIP_MODE)],
        ),
        spec(
            "TMP",
            "temperature",
            "Temperature reports and spot / area measurement",
            "D",
            f"{DOC} §五.12",
            extra_forms=[
                report(
                    F("hot_x_px", HexInt(3)),
                    F("hot_y_px", HexInt(2)),
                    F("hot_temp_c", HexInt(4, signed=True, scale=0.01, unit="degC")),
                    F("center_temp_c", HexInt(4, signed=True, scale=0.01, unit="degC")),
                    title="§12.1 hottest and centre",
                ),
                report(
                    F("hot_x_px", HexInt(3)),
                    F("hot_y_px", HexInt(2)),
                    F("hot_temp_c", HexInt(4, signed=True, scale=0.1, unit="degC")),
                    F("cold_x_px", HexInt(3)),
                    F("cold_y_px", HexInt(2)),
                    F("cold_temp_c", HexInt(4, signed=True, scale=0.1, unit="degC")),
                    F("center_temp_c", HexInt(4, signed=True, scale=0.1, unit="degC")),
                    title="§12.2 hottest, coldest and centre (#tP, 22 bytes)",
                ),
                request(
                    F("x_px", HexInt(3, max=640)),
                    F("y_px", HexInt(3, max=512)),
                    F("width_px", HexInt(2, max=64), "0 = spot", default=0),
                    F("height_px", HexInt(2, max=64), "0 = spot", default=0),
                    rw="r",
                    title="§12.3 spot / area query",
                ),
                report(
                    F("x_px", HexInt(3)),
                    F("y_px", HexInt(3)),
                    F("width_px", HexInt(2)),
                    F("height_px", HexInt(2)),
                    F("avg_temp_c", HexInt(4, signed=True, scale=0.01, unit="degC")),
                    rw="r",
                    title="§12.3 spot / area answer",
                ),
            ],
        ),
        spec(
            "TMR",
            "temperature_range",
            "Radiometry range",
            "D",
            f"{DOC} §五.12.4",
            write=[F("range", enum(2, {"00": ("low", "-20..150 °C"), "01": ("high", "-20..550 °C")}))],
        ),
        spec(
            "IMG",
            "palette",
            "Thermal palette",
            "D",
            f"{DOC} §五.13",
            write=[F("palette", PALETTES)],
            read=[F("palette", PALETTES)],
        ),
        spec(
            "DZM",
            "digital_zoom",
            "Digital zoom of the visible or thermal image",
            "D",
            f"{DOC} §五.14",
            write=[
                F("lens", enum(1, {"0": "visible", "1": "thermal"}), default="visible"),
                F(
                    "zoom",
                    OneOf(
                        enum(
                            2,
                            {
                                "0A": ("step_in", "Zoom in 0.5x"),
                                "0B": ("step_out", "Zoom out 0.5x"),
                                "0C": ("zoom_in", "Zoom in until stop"),
                                "0D": ("zoom_out", "Zoom out until stop"),
                                "0E": "stop",
                            },
                            toggles=("0A", "0B"),
                        ),
                        DecInt(2, scale=0.1, unit="x", max=8.0),
                    ),
                    "magnification step 0.1 (decimal 00..80), or an action",
                ),
            ],
            read=[
                F("thermal_zoom_x", DecInt(2, scale=0.1, unit="x")),
                F("visible_zoom_x", DecInt(2, scale=0.1, unit="x")),
            ],
        ),
        spec(
            "DFG",
            "defog",
            "Electronic defog",
            "D",
            f"{DOC} §五.15",
            write=[F("mode", enum(1, {"0": "off", "1": "auto", "2": "manual"})), F("strength", HexInt(2), "0..255")],
            read=[F("mode", enum(1, {"0": "off", "1": "auto", "2": "manual"})), F("strength", HexInt(2))],
        ),
        spec(
            "ENT",
            "encoding",
            "Video encoding",
            "D",
            f"{DOC} §五.17",
            write=[
                F("stream", enum(1, {"0": "stream0", "1": "stream1", "2": "main_record", "3": "second_record"})),
                F("codec", enum(1, {"0": "h264", "1": "h265"})),
            ],
        ),
        # -- beyond the document: what ArduPilot's TOPOTEK driver and other clients send ---------
        spec("PA2", "model_name", "Model name", "D", BEYOND, read=[F("model", Text(1, 15))], documented=False),
        spec(
            "TRC",
            "tracking",
            "Object tracking: start / stop; state query",
            "D",
            BEYOND,
            documented=False,
            write=[F("action", enum(2, {"00": "stop", "01": "start"}))],
            read=[
                F("reserved", RawData(1)),
                F(
                    "state",
                    enum(
                        1,
                        {
                            "0": "stopped",
                            "1": "waiting",
                            "2": "tracking",
                            "4": ("lens_cannot_track", "Lens cannot track"),
                        },
                    ),
                ),
            ],
        ),
        spec(
            "LOC",
            "tracking_box",
            "Tracking target box (binary: centre x, y, width, height, big-endian int16)",
            "D",
            BEYOND,
            documented=False,
            header="#tp",
            write=[
                F("x_px", BinInt(2, True, "big")),
                F("y_px", BinInt(2, True, "big")),
                F("width_px", BinInt(2, True, "big")),
                F("height_px", BinInt(2, True, "big")),
                F("reserved", RawData(2), default="0000"),
            ],
        ),
    ]
    sip = DeviceModel(
        "SIP",
        "topotek",
        "TOPOTEK SIP series (single / dual light)",
        (
            Endpoint("udp", 9003, "device port; replies to the sender (client port 9004 by convention)"),
            Endpoint("serial", None, "UART 115200 8N1"),
        ),
        yaw_range_deg=(-150.0, 150.0),
        pitch_range_deg=(-90.0, 90.0),
        roll_range_deg=(-90.0, 90.0),
        max_rate_deg_s=99.0 * u if u >= 0.5 else 60.0,
        thermal=True,
        visible_lenses=1,
        optical_zoom_max=10.0,
        digital_zoom_max=8.0,
        lrf_range_m=(5.0, 1500.0),
        host_address="P",
        # ArduPilot's driver (written with the vendor, fixed on hardware) sends and reads pitch
        # down-positive on the wire, although §四.3 says up-positive for angles (errata E8).
        wire_signs={"yaw": 1, "pitch": -1, "roll": 1},
        notes="RTSP rtsp://<ip>:554/stream=0 and stream=1.",
    )
    cmds = [replace(c, motion=True) if c.ident in MOTION else c for c in cmds]
    return Dialect(
        "topotek",
        'TOPOTEK "Udp&uart-Protocol" V1.1.3',
        cmds,
        [sip],
        host_addresses="UP",
        headers=("#TP", "#tp", "#tP", "#Tp"),
        options={"speed_unit_deg_s": speed_unit_deg_s, "binary_byteorder": binary_byteorder},
    )
