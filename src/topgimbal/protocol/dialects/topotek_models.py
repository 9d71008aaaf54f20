"""TOPOTEK model profiles: every per-model fact in one row per model (fields: `protocol.models`)."""

from __future__ import annotations

from ..models import DeviceModel, Endpoint, VideoStream

DOC = 'TOPOTEK "Udp&uart-Protocol" V1.1.3'
ARDUPILOT = "ArduPilot's TOPOTEK driver (AP_Mount_Topotek), written with the vendor and fixed on hardware"
FOV_ASSUMED = "URL from the document (网络设置); field of view assumed (errata E31)"

MODELS: tuple[DeviceModel, ...] = (
    DeviceModel(
        name="SIP",
        dialect="topotek",
        title="TOPOTEK SIP series (single / dual light)",
        endpoints=(
            Endpoint("udp", 9003, "device port; replies to the sender (client port 9004 by convention)"),
            Endpoint("serial", None, "UART 115200 8N1"),
        ),
        host_address="P",
        yaw_range_deg=(-150.0, 150.0),
        pitch_range_deg=(-90.0, 90.0),
        roll_range_deg=(-90.0, 90.0),
        max_rate_deg_s=99.0,
        thermal=True,
        visible_lenses=1,
        optical_zoom_max=10.0,
        digital_zoom_max=8.0,
        lrf_range_m=(5.0, 1500.0),
        # ArduPilot's driver sends and reads pitch down-positive on the wire (GIP, YPR, attitude),
        # although §四.3 says up-positive for angles (errata E9).
        wire_signs={"yaw": 1, "pitch": -1, "roll": 1},
        stream_rates_hz={"GAA": 10.0, "GIA": 10.0},
        # ArduPilot's driver: LAT, LON, ALT, AZI every 100 ms while it has a position; UTC a few
        # times after boot (here 1 Hz once a time is given: the camera's clock then never drifts).
        host_feeds={"LAT": 10.0, "LON": 10.0, "ALT": 10.0, "AZI": 10.0, "UTC": 1.0},
        echo_rules={"REC": "feedback with file index", "CAP": "feedback with file index"},
        quirks={"wire_signs": True, "version_digits_only": False},
        # "version@M": what the lens answers when VSN goes to M (TOPOTEK §三.8); the system's (§五.16)
        # is "version".
        identity={"version": "1.2.3", "version@M": "M3326", "model_name": "SIP", "serial_number": "SIP00000000001"},
        video=(
            VideoStream("main", "rtsp://{host}:554/stream=0", "visible", 56.0, (1.0, 10.0), FOV_ASSUMED),
            VideoStream("sub", "rtsp://{host}:554/stream=1", "thermal", 32.0, (1.0, 1.0), FOV_ASSUMED),
        ),
        sources=(DOC, ARDUPILOT),
        notes="RTSP rtsp://<ip>:554/stream=0 and stream=1. The model name comes from PA2; the version (VSN) as "
        "1.2.3 or 123.",
    ),
)

__all__ = ["MODELS"]
