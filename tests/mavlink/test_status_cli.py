"""`topgimbal mavlink --status SECONDS [--json]`: the bridge's own output says where the camera's
feeds come from (message, sender, rate, age) or why there is none, for a fake autopilot on loopback."""

from __future__ import annotations

import json
import os
import signal
import socket
import subprocess
import sys
import threading
from pathlib import Path
from typing import Any

import pytest
from pymavlink.dialects.v20 import common as ml

from topgimbal.cli.main import main
from topgimbal.cli.mavlink_status import status_lines
from topgimbal.sim import BackgroundSimulator

pytestmark = pytest.mark.loopback

SRC = str(Path(__file__).resolve().parents[2] / "src")


class Autopilot(threading.Thread):
    """An autopilot on a UDP socket: once the bridge's HEARTBEAT comes, it answers with a
    HEARTBEAT, GLOBAL_POSITION_INT and SYSTEM_TIME at 10 Hz (no attitude)."""

    def __init__(self) -> None:
        super().__init__(daemon=True)
        self.sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        self.sock.bind(("127.0.0.1", 0))
        self.sock.settimeout(0.1)
        self.port = self.sock.getsockname()[1]
        self.mav = ml.MAVLink(None, srcSystem=1, srcComponent=1)
        self.stop = threading.Event()

    def run(self) -> None:
        bridge = None
        t_ms = 0
        while not self.stop.is_set():
            try:
                _, bridge = self.sock.recvfrom(4096)
            except TimeoutError:
                pass
            if bridge is None:
                continue
            t_ms += 100
            for m in (ml.MAVLink_heartbeat_message(2, 3, 0, 0, 4, 3),
                      ml.MAVLink_global_position_int_message(t_ms, 473977420, 85455940, 500_000, 20_000, 0, 0, 0, 9000),
                      ml.MAVLink_system_time_message(1_700_000_000_000_000 + t_ms * 1000, t_ms)):  # fmt: skip
                self.sock.sendto(m.pack(self.mav), bridge)


def test_status_json_names_the_autopilots_messages_and_why_the_attitude_has_none() -> None:
    ap = Autopilot()
    ap.start()
    with BackgroundSimulator("C12", seed=41, listen={"udp": [("127.0.0.1", 0)]}) as c12:
        env = {**os.environ, "PYTHONPATH": SRC}
        proc = subprocess.Popen(
            [sys.executable, "-m", "topgimbal.cli.main", "mavlink", "--url", c12.url, "--model", "C12",
             "--mavlink", f"udpout:127.0.0.1:{ap.port}", "--status", "0.5", "--json", "--definition-http", "off"],
            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, env=env,
        )  # fmt: skip
        assert proc.stdout is not None
        lines: list[dict[str, Any]] = []
        timer = threading.Timer(120, proc.kill)  # a bound, not an expectation
        timer.start()
        try:
            for line in proc.stdout:
                lines.append(json.loads(line))
                feeds = lines[-1].get("feeds", {})
                if feeds.get("position", {}).get("source") and feeds.get("time", {}).get("source"):
                    break
        finally:
            proc.send_signal(signal.SIGINT)
            rest, err = proc.communicate(timeout=60)
            timer.cancel()
            ap.stop.set()
    assert proc.returncode == 0, err
    start, last = lines[0], lines[-1]
    assert start["mavlink_bridge"] == c12.url and start["model"] == "C12", start
    assert last["status"] == f"{c12.url} (C12)"
    pos, tim, att = last["feeds"]["position"], last["feeds"]["time"], last["feeds"]["attitude"]
    assert pos["message"] == "GLOBAL_POSITION_INT" and pos["source"] == "1/1" and pos["none"] is None
    assert tim["message"] == "SYSTEM_TIME" and tim["source"] == "1/1"
    assert last["feeds"]["heading"]["message"] == "GLOBAL_POSITION_INT"  # hdg 90: no attitude comes
    assert (
        att["message"] is None
        and att["none"] == "no AUTOPILOT_STATE_FOR_GIMBAL_DEVICE or ATTITUDE from the autopilot 1/1"
    )
    # the final status at the stop is JSON too (one object a line)
    assert all(json.loads(x) for x in rest.splitlines()), rest


def test_human_status_lines() -> None:
    info = {
        "feeds": {
            "position": {
                "message": "GLOBAL_POSITION_INT",
                "source": "1/1",
                "rate_hz": 10.0,
                "age_s": 0.05,
                "none": None,
            },
            "time": {"message": None, "source": None, "rate_hz": None, "age_s": None, "none": "no SYSTEM_TIME: why"},
        },
        "camera_feeds": "LAT 2 Hz (sending)",
    }
    assert status_lines("cam (C12)", info) == [
        "feeds of cam (C12):",
        "  position  GLOBAL_POSITION_INT from 1/1, 10 Hz, 0.05 s ago",
        "  time      none: no SYSTEM_TIME: why",
        "  sent to the camera: LAT 2 Hz (sending)",
    ]


@pytest.mark.parametrize("every", ["0.1", "x", "4000"])
def test_a_status_period_out_of_range_exits_2(every: str, capsys: pytest.CaptureFixture[str]) -> None:
    with pytest.raises(SystemExit) as exc:
        main(["mavlink", "--url", "udp://127.0.0.1:9", "--model", "C12", "--mavlink", "udpin:127.0.0.1:0",
              "--status", every])  # fmt: skip
    assert exc.value.code == 2 and "--status" in capsys.readouterr().err
