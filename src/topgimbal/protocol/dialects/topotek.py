"""TOPOTEK "Udp&uart-Protocol" V1.1.3 (SIP series), plus what real clients send beyond it.

The command table is data: one keyword-only row per identifier. Sections cite the document's
numbering (三 = M class, 四 = G class, 五 = D class). Values are as on the wire: no sign changes
here (the model profile's wire signs are applied by `protocol.signs`)."""

from __future__ import annotations

from collections.abc import Mapping

from ..commands import CommandSpec
from ..dialect import Dialect
from ..fields import BinInt, Bitrate, DecFloat, DecInt, Field, HexInt, OneOf, RawData, Text, Timestamp, enum
from ..forms import REQUEST, Form
from . import _shared as shared
from ._build import F, angle, attitude_fields, command, place, rate, report, request
from .topotek_models import MODELS

DOC = "TOPOTEK"
TITLE = 'TOPOTEK "Udp&uart-Protocol" V1.1.3'
CLIENTS = f"{shared.BEYOND} (real clients: ArduPilot's TOPOTEK driver and others)"
RATE_STEPS = 99

PTZ = shared.ptz_actions(
    {
        "06": ("lock", "Lock heading", "锁头"),
        "07": ("follow", "Follow", "跟随"),
        "0A": ("look_down", "One-key look down", "一键向下"),
    }
)
PALETTES = enum(
    2,
    {
        "00": ("white_hot", "White hot", "白热"),
        "01": ("lava", "Lava", "熔岩"),
        "02": ("ironbow", "Ironbow", "铁红"),
        "03": ("hot_iron", "Hot iron", "热铁"),
        "04": ("medical", "Medical", "医疗"),
        "05": ("arctic", "Arctic", "北极"),
        "06": ("rainbow1", "Rainbow 1", "彩虹1"),
        "07": ("rainbow2", "Rainbow 2", "彩虹2"),
        "08": ("red_tint", "Red tint", "描红"),
        "09": ("black_hot", "Black hot", "黑热"),
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
REC_FEEDBACK = enum(2, {"00": ("stopped", "Recording stopped"), "11": ("started", "Recording started")})
FILE_INDEX = HexInt(8)
PHOTO_MODE = enum(
    2,
    {
        "01": ("visible_thermal", "Visible + thermal"),
        "02": ("visible", "Visible only"),
        "03": ("thermal", "Thermal only"),
        "05": ("radiometric", "Visible, thermal and radiometric file"),
    },
)
STREAM = enum(1, {"0": ("record", "Recording"), "1": ("photo", "Photo"), "2": ("rtsp", "RTSP")})
RESOLUTION = enum(1, {"0": "3840x2160", "1": "1920x1080", "2": "1280x720", "3": "640x480"})
ROTATION = enum(2, {"00": ("normal", "0°"), "02": ("rotate_180", "180°")})
DEFOG = enum(1, {"0": "off", "1": "auto", "2": "manual"})
SWH_DEVICE = enum(
    1, {"5": ("rangefinder_5v", "5 V: rangefinder / dust sensor"), "C": ("light_12v", "12 V: fill light")}
)
TRACKING_STATE = enum(
    1, {"0": "stopped", "1": "waiting", "2": "tracking", "4": ("lens_cannot_track", "Lens cannot track")}
)


def _angle_cmds(prefix: str, frame: str, section: str, name_prefix: str, role: str) -> list[CommandSpec]:
    sp = F("speed_deg_s", HexInt(2, scale=0.1, unit="deg/s", max=9.9), "slew speed 0..99 x 0.1 deg/s", default=9.9)
    yaw = angle("yaw_deg", -150, 150, f"yaw ({frame}), right-positive")
    pitch = angle(
        "pitch_deg", -90, 90, f"pitch ({frame}); the document says up-positive, ArduPilot finds down-positive"
    )
    roll = angle("roll_deg", -90, 90, f"roll ({frame})")
    ys = F("yaw_speed_deg_s", sp.codec, sp.description, default=9.9)
    ps = F("pitch_speed_deg_s", sp.codec, sp.description, default=9.9)

    def row(suffix: str, name: str, title: str, fields: list[Field]) -> CommandSpec:
        return command(
            ident=f"{prefix}{suffix}",
            name=f"{name_prefix}{name}",
            title=f"{title}, {frame}",
            section=section,
            role=role,
            motion=True,
            write=fields,
            **place("G", "gimbal"),
        )

    return [
        row("Y", "yaw_angle", "Yaw angle", [yaw, sp]),
        row("P", "pitch_angle", "Pitch angle", [pitch, sp]),
        row("R", "roll_angle", "Roll angle", [roll, sp]),
        row("M", "yaw_pitch_angle", "Yaw and pitch angles", [yaw, ys, pitch, ps]),
    ]  # fmt: skip


def _temperature(scale: float) -> HexInt:
    return HexInt(4, signed=True, scale=scale, unit="degC")


def commands(u: float, bo: str) -> list[CommandSpec]:
    """Every TOPOTEK command, as data. `u`: the GS*/RPS/YPR rate step in deg/s (errata E8);
    `bo`: the GPS / UAV struct byte order (errata E18)."""
    on_off = shared.on_off_codec()
    pos = F("zoom_pos", HexInt(4, signed=True), "zoom motor position", state_key="zoom.position")
    att = attitude_fields(state="attitude")
    earth = attitude_fields(state="earth_attitude")
    pitch_note = "down-positive on the wire, as the document says for speeds"
    lens = place("M", "lens")
    gimbal = place("G", "gimbal")
    camera = place("D", "camera")
    thermal = place("D", "thermal")
    position = place("D", "position")
    tmp_sect = f"{DOC} §五.12"
    return [
        shared.error_frame(f"{DOC} §二 (response mechanism, as SkyDroid §2.3.2)"),
        # -- M class: lens -----------------------------------------------------------------------
        *shared.lens_commands({"ZMC": f"{DOC} §三.1.1", "FCC": f"{DOC} §三.2.1", "ZFP": f"{DOC} §三.3", "IRC": f"{DOC} §三.6"}),
        command(ident="ZOM", name="zoom_position", title="Read the zoom position", section=f"{DOC} §三.1.2",
                role="zoom_position", read=[pos], **lens),
        command(ident="FOC", name="focus_position", title="Read the focus position", section=f"{DOC} §三.2.2",
                role="focus_position",
                read=[F("focus_pos", HexInt(4, signed=True), "focus motor position", state_key="focus.position")],
                **lens),
        command(ident="ZMP", name="zoom_report", title="Magnification and zoom position, sent after each zoom change",
                section=f"{DOC} §三.4", role="zoom_report",
                extra_forms=[report(F("magnification_x", DecInt(3, scale=0.1, unit="x"), "optical magnification",
                                      state_key="zoom.optical_x"), pos, rw="r")],
                **lens),
        command(ident="SWH", name="aux_power", title="Power an auxiliary device (not yet supported by the device)",
                section=f"{DOC} §三.5", role="aux_power", address="M", group="system",
                write=[F("device", SWH_DEVICE), F("state", enum(1, {"0": "off", "1": "on"}))],
                read=[F("device", SWH_DEVICE), F("state", enum(1, {"0": "off", "1": "on"}))]),
        command(ident="ATE", name="ate_mode", title="ATE (factory test) mode", section=f"{DOC} §三.7",
                role="factory_test", address="M", group="system", write=[F("state", on_off)]),
        command(ident="VSN", name="version", title="Firmware version", section=f"{DOC} §三.8 (lens, M) and §五.16 (system, D)",
                role="version", address="D", group="system", addresses=("M",),
                read=[F("version", Text(1, 15), "version text: M3326 (lens), two characters (system), 1.2.3 or 123 "
                        "(ArduPilot)", state_key="version")]),
        command(ident="MUL", name="magnification", title="Optical magnification", section=f"{DOC} §三.9",
                role="optical_zoom", write=[F("magnification_x", DecInt(4, scale=0.1, unit="x", min=1.0))],
                read=[F("magnification_x", DecInt(4, scale=0.1, unit="x"), state_key="zoom.optical_x")], **lens),
        command(ident="APC", name="aperture_control", title="Aperture: - / + / stop", section=f"{DOC} §三.10",
                role="aperture",
                write=[F("action", enum(2, {"00": "stop", "01": ("close", "Aperture -"), "02": ("open", "Aperture +")}))],
                **lens),
        command(ident="LRF", name="rangefinder",
                title="Laser rangefinder: control (to M) and distance results (from the device)",
                section=f"{DOC} §五.9", role="range", address="M", group="range",
                write=[F("action", enum(2, {"00": "stop", "01": ("on", "Rangefinder on"),
                                            "02": ("single", "Single measurement"),
                                            "03": ("continuous", "Continuous measurement (00 stops)")},
                                        toggles="02"))],
                extra_forms=[report(F("distance_m", DecFloat(None, 1, "m", 0, 99999.9, none_tokens=(b"ERR",), pad=7),
                                      "distance, or null when the measurement failed (ERR)", state_key="range_m"),
                                    title="result")],
                notes="Result: X1X2X3X4X5.X6 metres; ERR = failed (too near or too far)."),
        # -- G class: gimbal ---------------------------------------------------------------------
        command(ident="PTZ", name="gimbal_control", title="Gimbal control codes", section=f"{DOC} §四.1",
                role="gimbal_control", write=[F("action", PTZ)], motion=True, **gimbal),
        *shared.rate_commands(f"{DOC} §四.2", u, RATE_STEPS, {"pitch": pitch_note}, gsm_notes=True, header="#tp"),
        command(ident="RPS", name="roll_pitch_rate", title="Roll and pitch speed", section=f"{DOC} §四.2", role="rate",
                write=[rate("roll", u, RATE_STEPS), rate("pitch", u, RATE_STEPS, pitch_note)], header="#tp",
                motion=True, **gimbal),
        command(ident="YPR", name="yaw_pitch_roll_rate", title="Yaw, pitch and roll speed", section=f"{DOC} §四.2",
                role="rate", header="#tp", motion=True,
                write=[rate("yaw", u, RATE_STEPS), rate("pitch", u, RATE_STEPS, pitch_note), rate("roll", u, RATE_STEPS)],
                **gimbal),
        *_angle_cmds("GA", "body frame", f"{DOC} §四.3.1 (magnetic encoder)", "", "angle"),
        *_angle_cmds("GI", "earth frame", f"{DOC} §四.3.2 (gyro)", "earth_", "earth_angle"),
        command(ident="GAC", name="attitude", title="Read the attitude (magnetic encoder, body frame)",
                section=f"{DOC} §四.3.3", role="attitude", read=att, **gimbal),
        command(ident="GAA", name="attitude_stream", title="Attitude output on / off (GAC frames)",
                section=f"{DOC} §四.3.4", role="attitude_stream",
                write=[F("state", on_off)], read=[F("state", on_off)], **gimbal),
        command(ident="GIC", name="gyro_attitude", title="Read the attitude (gyro, earth frame)",
                section=f"{DOC} §四.3.5", role="earth_attitude", read=earth, **gimbal),
        command(ident="GIA", name="gyro_attitude_stream", title="Gyro attitude output on / off; the stream itself",
                section=f"{DOC} §四.3.6", role="earth_attitude_stream",
                write=[F("state", on_off)], read=[F("state", on_off)],
                extra_forms=[
                    report(*earth, rw="r", title="stream (first 12 characters; ArduPilot)"),
                    report(*earth, F("extra", RawData(None, min_bytes=1), "characters after the first 12"), rw="r",
                           title="stream with extra data"),
                    report(*earth, title="stream (w)"),
                ],
                **gimbal),
        command(ident="GMS", name="motors", title="Gimbal motors on / off", section=f"{DOC} §四.4", role="motors",
                write=[F("state", on_off)], read=[F("state", on_off, state_key="motors")], **gimbal),
        command(ident="VER", name="serial_number", title="Serial number (some models)", section=f"{DOC} §四.5",
                role="serial_number", address="G", group="system",
                read=[F("serial", Text(1, 15), "14 characters", state_key="serial_number")]),
        # -- D class: system and image -----------------------------------------------------------
        shared.recording_command(f"{DOC} §五.1", [report(F("state", REC_FEEDBACK), F("file_index", FILE_INDEX,
                          "stream_0_<idx>.h264"), title="feedback with file index")]),
        command(ident="CAP", name="photo", title="Take a photo", section=f"{DOC} §五.2", role="photo",
                write=[F("mode", PHOTO_MODE, default="visible_thermal")], repeatable=False,
                extra_forms=[report(F("state", enum(2, {"11": ("taken", "Photo taken")})),
                                    F("file_index", FILE_INDEX, "snap_0_<idx>.jpeg"), title="feedback with file index")],
                **camera),
        command(ident="VID", name="resolution", title="Resolution of a stream", section=f"{DOC} §五.3",
                role="resolution", write=[F("stream", STREAM), F("resolution", RESOLUTION)],
                read=[F("stream", STREAM), F("resolution", RESOLUTION, factory="1920x1080")], **camera),
        command(ident="BIT", name="bitrate", title="RTSP stream=0 bitrate", section=f"{DOC} §五.4", role="bitrate",
                write=[F("bitrate_kbps", Bitrate())], read=[F("bitrate_kbps", Bitrate(), factory=4000)], **camera),
        command(ident="SDC", name="sd_card", title="SD card capacity (remaining or total)", section=f"{DOC} §五.5",
                role="sd_capacity",
                read=[F("capacity_mb", HexInt(5, unit="MB", none_tokens=(b"NNNNN",)), "null = no card",
                        state_key="sd.capacity_mb")],
                read_request=Form("r", REQUEST, (F("which", enum(2, {"00": "remaining", "01": "total"}),
                                                  default="remaining"),), title="query"),
                **camera),
        command(ident="ROT", name="rotation", title="Image flip / mirror", section=f"{DOC} §五.6", role="rotation",
                write=[F("rotation", ROTATION)], read=[F("rotation", ROTATION)], **camera),
        *shared.network_commands({"IPV": f"{DOC} §五.7", "GTW": f"{DOC} §五.7", "RST": f"{DOC} §五.7"}, dns=False),
        *shared.position_commands({"LAT": f"{DOC} §五.8.2, §五.8.7", "LON": f"{DOC} §五.8.1, §五.8.7", "ALT": f"{DOC} §五.8.3"}),
        command(ident="AZI", name="azimuth", title="Vehicle ground course (true north)", section=f"{DOC} §五.8.4",
                role="azimuth", write=[F("azimuth_deg", DecFloat(None, 1, "deg", 0, 359.9, pad=5))], **position),
        command(ident="GPS", name="gps", title="Vehicle position (packed binary, sTPGpsInfo)", section=f"{DOC} §五.8.5",
                role="vehicle_position", header="#tp",
                write=[F("heading_deg", BinInt(2, True, bo, 0.01, "deg"), "vehicle heading (unit not stated; 0.01 deg assumed)"),
                       F("lon_deg", BinInt(4, True, bo, 1e-7, "deg", -180, 180)),
                       F("lat_deg", BinInt(4, True, bo, 1e-7, "deg", -90, 90)),
                       F("alt_m", BinInt(4, True, bo, 0.001, "m", -500, 10000))],
                **position),
        command(ident="UAV", name="vehicle_attitude", title="Vehicle attitude (packed binary, sTPUavInfo)",
                section=f"{DOC} §五.8.6", role="vehicle_attitude", header="#tp",
                write=[F("yaw_deg", BinInt(2, False, bo, 0.01, "deg", 0, 360), "declared int16 but 0..36000: sent unsigned"),
                       F("pitch_deg", BinInt(2, True, bo, 0.01, "deg", -90, 90), "down-positive (struct comment)", sign=-1),
                       F("roll_deg", BinInt(2, True, bo, 0.01, "deg", -90, 90), "right-positive"),
                       F("speed_m_s", BinInt(2, False, bo, 0.01, "m/s", 0, 200)),
                       F("path_angle_deg", BinInt(2, False, bo, 0.01, "deg", 0, 360))],
                **position),
        command(ident="TIM", name="time", title="Local (Beijing) time", section=f"{DOC} §五.10", role="time",
                write=[F("time", Timestamp("%Y%m%d%H%M%S"))], **position),
        command(ident="UTC", name="utc_time", title="UTC time", section=f"{DOC} §五.10", role="utc_time",
                write=[F("time", Timestamp("%H%M%S%d%m%y"))], **position),
        command(ident="PIP", name="picture_in_picture", title="Picture-in-picture layout", section=f"{DOC} §五.11",
                role="picture_in_picture",
                write=[F("secondary", PIP_MODE, "second visible lens (dual-visible models)", default="main_only"),
                       F("mode", PIP_MODE)],
                read=[F("secondary", PIP_MODE), F("mode", PIP_MODE)], **camera),
        command(ident="TMP", name="temperature", title="Temperature reports and spot / area measurement",
                section=tmp_sect, role="temperature",
                extra_forms=[
                    report(F("hot_x_px", HexInt(3)), F("hot_y_px", HexInt(2)), F("hot_temp_c", _temperature(0.01)),
                           F("center_temp_c", _temperature(0.01), state_key="temperature.center_c"),
                           title="hottest and centre", section=f"{tmp_sect}.1"),
                    report(F("hot_x_px", HexInt(3)), F("hot_y_px", HexInt(2)), F("hot_temp_c", _temperature(0.1)),
                           F("cold_x_px", HexInt(3)), F("cold_y_px", HexInt(2)), F("cold_temp_c", _temperature(0.1)),
                           F("center_temp_c", _temperature(0.1), state_key="temperature.center_c"),
                           title="hottest, coldest and centre (#tP, 22 bytes)", section=f"{tmp_sect}.2"),
                    request(F("x_px", HexInt(3, max=640)), F("y_px", HexInt(3, max=512)),
                            F("width_px", HexInt(2, max=64), "0 = spot", default=0),
                            F("height_px", HexInt(2, max=64), "0 = spot", default=0),
                            rw="r", title="spot / area query", section=f"{tmp_sect}.3"),
                    report(F("x_px", HexInt(3)), F("y_px", HexInt(3)), F("width_px", HexInt(2)),
                           F("height_px", HexInt(2)), F("avg_temp_c", _temperature(0.01)), rw="r",
                           title="spot / area answer", section=f"{tmp_sect}.3"),
                ],
                **thermal),
        command(ident="TMR", name="temperature_range", title="Radiometry range", section=f"{DOC} §五.12.4",
                role="temperature_range",
                write=[F("range", enum(2, {"00": ("low", "-20..150 °C"), "01": ("high", "-20..550 °C")}))], **thermal),
        shared.palette_command(f"{DOC} §五.13", PALETTES),
        command(ident="DZM", name="digital_zoom", title="Digital zoom of the visible or thermal image",
                section=f"{DOC} §五.14", role="digital_zoom", address="D", group="lens",
                write=[F("lens", enum(1, {"0": "visible", "1": "thermal"}), default="visible"),
                       F("zoom", OneOf(shared.DZM_ACTIONS, DecInt(2, scale=0.1, unit="x", max=8.0)),
                         "magnification step 0.1 (decimal 00..80), or an action")],
                read=[F("thermal_zoom_x", DecInt(2, scale=0.1, unit="x"), state_key="zoom.thermal_digital_x"),
                      F("visible_zoom_x", DecInt(2, scale=0.1, unit="x"), state_key="zoom.digital_x")],
                extra_forms=shared.digital_zoom_client_forms(two_char=True)),
        command(ident="DFG", name="defog", title="Electronic defog", section=f"{DOC} §五.15", role="defog",
                write=[F("mode", DEFOG), F("strength", HexInt(2), "0..255")],
                read=[F("mode", DEFOG), F("strength", HexInt(2))], **camera),
        command(ident="ENT", name="encoding", title="Video encoding", section=f"{DOC} §五.17", role="encoding",
                write=[F("stream", enum(1, {"0": "stream0", "1": "stream1", "2": "main_record", "3": "second_record"})),
                       F("codec", enum(1, {"0": "h264", "1": "h265"}))],
                **camera),
        # -- beyond the document: what ArduPilot's TOPOTEK driver and other clients send ---------
        command(ident="PA2", name="model_name", title="Model name", section=CLIENTS, role="model_name",
                address="D", group="system", documented=False,
                read=[F("model", Text(1, 15), state_key="model_name")]),
        command(ident="TRC", name="tracking", title="Object tracking: start / stop; state query", section=CLIENTS,
                role="tracking", address="D", group="tracking", documented=False,
                write=[F("action", enum(2, {"00": "stop", "01": "start",
                                            "02": ("ready", "Ready to track: wait for a target box (LOC)")}))],
                read=[F("reserved", RawData(1)), F("state", TRACKING_STATE, state_key="tracking")]),
        command(ident="LOC", name="tracking_box",
                title="Tracking target box (binary: centre x, y, width, height, big-endian int16)", section=CLIENTS,
                role="tracking_box", address="D", group="tracking", documented=False, header="#tp",
                write=[F("x_px", BinInt(2, True, "big")), F("y_px", BinInt(2, True, "big")),
                       F("width_px", BinInt(2, True, "big")), F("height_px", BinInt(2, True, "big")),
                       F("reserved", RawData(2, binary=True), default="0000")]),
    ]  # fmt: skip


def topotek(
    *, speed_unit_deg_s: float = 1.0, binary_byteorder: str = "little", destinations: Mapping[str, str] | None = None
) -> Dialect:
    """Build the TOPOTEK dialect.

    speed_unit_deg_s: GS*/RPS/YPR step. The table says deg/s, the text 0.1 deg/s (errata E8);
    binary_byteorder: GPS/UAV struct byte order, which the document does not state (errata E18);
    destinations: {ident: address} for firmware that wants a command elsewhere.
    """
    u = speed_unit_deg_s
    return shared.build_dialect(
        "topotek",
        TITLE,
        commands(u, binary_byteorder),
        MODELS,
        # 99 steps; 60 deg/s when steps are too fine to be the real limit.
        max_rate_deg_s=RATE_STEPS * u if u >= 0.5 else 60.0,
        options={"speed_unit_deg_s": u, "binary_byteorder": binary_byteorder},
        destinations=destinations,
        host_addresses="UP",
        headers=("#TP", "#tp", "#tP", "#Tp"),
    )


__all__ = ["DOC", "TITLE", "commands", "topotek"]
