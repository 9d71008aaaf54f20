"""SkyDroid model profiles: every per-model fact in one row per model (fields: `protocol.models`).

Support sets come from each document section's 支持 line (errata E26); the C11 and the C13's
gimbal come from public reports (errata E27, E28). Facts from public reports name their source in
`sources` and in docs/errata.md."""

from __future__ import annotations

from dataclasses import replace
from typing import Any

from ..models import DeviceModel, Endpoint, VideoStream

# Commands with no 支持 line apply to every model; HWV and MOD are asked of every model by clients.
COMMON = frozenset(
    {"ERE", "AWB", "IPV", "GTW", "DNS", "BNS", "RST", "RTF", "ZMC", "FCC", "ZFP", "IRC", "LAT", "LON", "ALT",
     "MNU", "EVS", "TMP", "HWV", "MOD"}
)  # fmt: skip
GIMBAL = frozenset({"PTZ", "GSY", "GSP", "GSR", "GSM", "GAY", "GAP", "GAR", "GAM", "GAA", "GAC"})
CAMERA = frozenset({"REC", "CAP", "TIM", "VOM", "VER"})
C12_ONLY = frozenset({"SUM", "GOT", "FAE", "FAI", "VID", "SDC", "IQE", "DZM", "IMG", "UID"})
C13_THERMAL = frozenset({"TSM", "TDI", "TIB", "TIC", "TAR", "TTR", "TGM", "SLR"})
# The C13's motion commands: not in its document's support lines, but public reports drive them (E28).
C13_MOTION = frozenset({"PTZ", "GSY", "GSP", "GSM", "GAY", "GAP", "GAM"})
# The C11 (E27): a two-axis gimbal camera, no roll; camera, SD card, time, digital zoom, FC attitude.
C11 = COMMON | (GIMBAL - {"GSR", "GAR"}) | {"FAE", "FAI", "REC", "CAP", "SDC", "VER", "TIM", "DZM"}

ARDUPILOT = "ArduPilot's SkyDroid driver pull request (AP_Mount_SkyDroid, tested on C11 hardware, C13 on the bench)"
GROUND_STATIONS = "ground-station forks and SkyDroid's decompiled Android SDK driving a C12 (issue 10 reports)"
DOC = 'SkyDroid "TOP 协议" V1.1.5'
VIDEO_ASSUMED = "assumption (errata E31): the document gives no video URL or field of view"


def _video(hfov_visible: float, zoom_x: float = 1.0, thermal_hfov: float | None = None) -> tuple[VideoStream, ...]:
    out = [
        VideoStream("main", "rtsp://{host}:554/stream=1", "visible", hfov_visible, (1.0, zoom_x), VIDEO_ASSUMED),
    ]
    if thermal_hfov is not None:
        out.append(VideoStream("thermal", "rtsp://{host}:554/stream=2", "thermal", thermal_hfov, (1.0, 1.0),
                               VIDEO_ASSUMED))  # fmt: skip
    return tuple(out)


def _model(name: str, title: str, version: str, **kw: Any) -> DeviceModel:
    """A SkyDroid profile. Identity answers: the firmware `version`, the name as MOD answers it and
    H1.0 as HWV does on every unit seen; sources: the document unless given."""
    kw.setdefault("sources", (DOC,))
    identity = {"version": version, "model_name": name, "hardware_version": "H1.0"}
    return DeviceModel(name=name, dialect="skydroid", title=f"SkyDroid {title}", identity=identity, **kw)


UDP_5000 = Endpoint("udp", 5000)
C10 = _model("C10", "C10", "V1.2.0", endpoints=(UDP_5000, Endpoint("tcp", 5000), Endpoint("udp", 9002)),
             commands=COMMON | GIMBAL | CAMERA, optical_zoom_max=10.0, video=_video(60.0, 10.0))  # fmt: skip

MODELS: tuple[DeviceModel, ...] = (
    C10,
    # The C10 Pro: a C10 with the extended settings (EXT), on UDP only.
    replace(
        C10,
        name="C10Pro",
        title="SkyDroid C10 Pro",
        endpoints=(UDP_5000,),
        commands=COMMON | GIMBAL | CAMERA | {"EXT"},
        identity={**C10.identity, "model_name": "C10Pro"},
    ),
    _model(
        "C11",
        "C11 (two-axis, visible; from public reports)",
        "V1.0.78",
        endpoints=(Endpoint("udp", 5000, "UDP only; the host's source address is always U"),),
        commands=C11,
        yaw_range_deg=(-90.0, 90.0),
        pitch_range_deg=(-90.0, 10.0),
        roll_range_deg=(0.0, 0.0),
        max_rate_deg_s=63.5,
        dialect_options={"speed_unit_deg_s": 0.5},
        destinations={"DZM": "M"},
        max_frame_bytes=28,
        wire_signs={"rate.yaw": -1},
        ignored=frozenset({"GAM", "GSM", "GAY", "GAP"}),
        stream_rates_hz={"GAA": 50.0},
        host_feeds={"FAI": 10.0, "TIM": 1.0},
        host_setup=(("FAE", {"state": "on"}),),
        quirks={
            "ignored_commands": True,
            "needs_video_output": True,
            "no_clock": True,
            "frame_size_limit": True,
            "fixed_stream_rate": True,
            "wire_signs": True,
            "speed_unit": True,
            "strict_destinations": True,
        },
        video=_video(60.0),
        sources=(ARDUPILOT,),
        notes="Absolute angles (GAM, GAY, GAP) and GSM are ignored: point by closing the loop over GSY / GSP "
        "rates fed by the GAC stream. PTZ 05 centres. Roll cannot be commanded. Send FAE 01, then FAI at 10 Hz; "
        "TIM at 1 Hz (no clock). Camera commands take effect only once video output has started.",
    ),
    _model(
        "C12",
        "C12 (visible + thermal)",
        "010502",
        endpoints=(Endpoint("udp", 5000, "SkyDroid's assistant app uses this port too: close it on the same host"),),
        alternate_endpoints=(Endpoint("udp", 12580, "seen on some units"),),
        commands=COMMON | GIMBAL | CAMERA | C12_ONLY | {"EXT", "TAS"},
        pitch_range_deg=(-45.0, 45.0),
        thermal=True,
        digital_zoom_max=4.0,
        limits={
            ("TAS", "interval_s"): (0.0, 25.0),
            ("GAP", "pitch_deg"): (-45.0, 45.0),
            ("GAM", "pitch_deg"): (-45.0, 45.0),
        },
        wire_signs={"rate.yaw": -1},
        min_command_gap_s=0.04,
        # Within the 40 ms pacing (25 frames/s): FAI 10 Hz as on the C11, the position 2 Hz, TIM 1 Hz.
        host_feeds={"FAI": 10.0, "LAT": 2.0, "LON": 2.0, "ALT": 2.0, "TIM": 1.0},
        host_setup=(("FAE", {"state": "on"}),),
        slow_answers=frozenset({"MOD"}),
        quirks={"ver_wrong_length": True, "wire_signs": True, "late_answers": False, "command_pacing": False},
        video=_video(60.0, 1.0, thermal_hfov=45.0),
        sources=(DOC, GROUND_STATIONS),
        notes="GAY's yaw sign is opposite to GSY's (here: GSY inverted as on the C11 / C13; GAY and GAC as "
        "documented). Leave 40 ms "
        "between commands. MOD may answer minutes late or never.",
    ),
    _model(
        "C13",
        "C13 (thermal + laser range)",
        "V1.1.0",
        endpoints=(UDP_5000,),
        commands=COMMON | C13_THERMAL | {"TAS"} | C13_MOTION,
        roll_range_deg=(-45.0, 45.0),
        thermal=True,
        lrf_range_m=(0.5, 100.0),
        limits={("TAS", "interval_s"): (5.0, 100.0)},
        wire_signs={"rate.yaw": -1},
        gimbal_header="#TP",
        no_echo=C13_MOTION,
        stop_repeats=3,
        quirks={"no_motion_echo": True, "stop_coasts": True, "gimbal_header_required": True, "wire_signs": True},
        video=_video(60.0, thermal_hfov=32.0),
        sources=(DOC, ARDUPILOT),
        notes="Motion commands are often not acknowledged and a stop may coast: send stops 3 times. G-class frames "
        "must use #TP (#tp angle commands were ignored). GSY yaw is inverted.",
    ),
    _model(
        "C20",
        "C20",
        "V1.0.3",
        endpoints=(Endpoint("tcp", 5000),),
        commands=COMMON | GIMBAL,
        video=_video(60.0),
    ),
)

__all__ = ["C11", "C13_MOTION", "CAMERA", "COMMON", "GIMBAL", "MODELS"]
