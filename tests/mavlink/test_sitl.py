"""ArduPilot SITL drives the bridge as a MAVLink gimbal device (MNT1_TYPE=6).

Runs only where ARDUPILOT_SITL points at an `arducopter` SITL binary; skipped (not passed)
elsewhere: building ArduPilot is not part of this project's setup."""

from __future__ import annotations

import asyncio
import contextlib
import os
import socket
import tempfile
from pathlib import Path

import pytest
from pymavlink.dialects.v20 import common as ml

from .conftest import Peer, eventually

SITL = os.environ.get("ARDUPILOT_SITL")


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return int(s.getsockname()[1])


@pytest.mark.skipif(
    not SITL, reason="ARDUPILOT_SITL is not set to an arducopter SITL binary: the MNT1_TYPE=6 test cannot run"
)
async def test_ardupilot_drives_the_gimbal_device(rig_factory) -> None:
    assert SITL is not None and Path(SITL).is_file(), f"ARDUPILOT_SITL={SITL!r} is not a file"
    base = _free_port()
    work = tempfile.mkdtemp(prefix="sitl-")
    params = Path(work, "gimbal.parm")
    params.write_text("MNT1_TYPE 6\nMNT1_PITCH_MIN -90\nMNT1_PITCH_MAX 90\nMNT1_YAW_MIN -90\nMNT1_YAW_MAX 90\n"
                      "SERIAL2_PROTOCOL 2\n")  # fmt: skip
    # SERIAL2 (uartC) as a TCP client to the bridge's tcpin link; SERIAL0 for our GCS peer.
    r = await rig_factory("C12", role="device", endpoints=["udpin:127.0.0.1:0", "tcpin:127.0.0.1:0"])
    _, tcp_port = r.bridge.addresses[1]
    proc = await asyncio.create_subprocess_exec(
        SITL, "--model", "quad", "--speedup", "1", "--defaults", str(params), "-I0", "--base-port", str(base),
        "--serial2", f"tcpclient:127.0.0.1:{tcp_port}", cwd=work,
        stdout=asyncio.subprocess.DEVNULL, stderr=asyncio.subprocess.DEVNULL,
    )  # fmt: skip
    try:
        reader, writer = None, None
        for _ in range(100):
            with contextlib.suppress(OSError):
                reader, writer = await asyncio.open_connection("127.0.0.1", base)
                break
            await asyncio.sleep(0.2)
        assert writer is not None, "SITL did not open its MAVLink port"
        gcs = Peer(sysid=255)
        parser = ml.MAVLink(None)

        def send(msg: object) -> None:
            writer.write(msg.pack(gcs.mav))  # type: ignore[attr-defined]

        # point the mount through the autopilot's own gimbal manager: it drives our device
        for _ in range(60):
            send(ml.MAVLink_command_long_message(1, 1, ml.MAV_CMD_DO_MOUNT_CONTROL, 0, -30, 0, 20, 0, 0, 0,
                                                 ml.MAV_MOUNT_MODE_MAVLINK_TARGETING))  # fmt: skip
            with contextlib.suppress(asyncio.TimeoutError):
                data = await asyncio.wait_for(reader.read(4096), 0.5)  # type: ignore[union-attr]
                parser.parse_buffer(data)
            if r.bridge.device.set_attitude_received and abs(r.sim.gimbal.pitch_deg + 30) < 1:
                break
        assert r.bridge.device.set_attitude_received > 0, "ArduPilot sent no GIMBAL_DEVICE_SET_ATTITUDE"
        await eventually(lambda: abs(r.sim.gimbal.pitch_deg + 30) < 1 and abs(r.sim.gimbal.yaw_deg - 20) < 1, 30)
    finally:
        proc.terminate()
        with contextlib.suppress(Exception):
            await asyncio.wait_for(proc.wait(), 10)
