"""ArduPilot SITL in front of the bridge, as a user sets it up (issue 22): `MNT1_TYPE 6` and
`CAM1_TYPE 6` on the autopilot's SERIAL2 (`SERIAL2_PROTOCOL 2`), which is the bridge in the
gimbal device role, which fronts the simulated C12; a ground station talks only to the autopilot
(its SERIAL0). One test, in steps, each with a generous time-based deadline:

1. the autopilot finds the gimbal ("Mount: SkyDroid C12" about 10 s after boot) and takes its
   limits from GIMBAL_DEVICE_INFORMATION (MNT1_PITCH_MIN/MAX, MNT1_YAW_MIN/MAX);
2. the mount is healthy (no "PreArm: Mount: not healthy" on MAV_CMD_RUN_PREARM_CHECKS);
3. body-frame targets (DO_MOUNT_CONTROL, DO_GIMBAL_MANAGER_PITCHYAW) and earth-frame targets
   (DO_GIMBAL_MANAGER_PITCHYAW with YAW_LOCK, DO_SET_ROI_LOCATION) reach the simulated camera
   within 1 deg, every command ACCEPTED by the autopilot;
4. a photo through the autopilot (DO_DIGICAM_CONTROL: the simulator's photo count goes up);
5. the camera dies: the autopilot reports "PreArm: Mount: not healthy".

Runs only where ARDUPILOT_SITL points at an `arducopter` SITL binary; skipped (not passed)
elsewhere: building ArduPilot is not part of this project's setup (see docs/mavlink.md). SITL's
output is kept in a file whose tail is printed when the test fails. The times to reach each
target and the acknowledgements are printed (`pytest -s`)."""

from __future__ import annotations

import asyncio
import contextlib
import math
import os
import socket
import tempfile
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

import pytest
from pymavlink.dialects.v20 import common as ml

from topgimbal.mavlink.geo import Position, look_at
from topgimbal.protocol import get_model

SITL = os.environ.get("ARDUPILOT_SITL")
AUTOPILOT = (1, 1)
BOOT_S = 90.0  # SITL's boot plus its 10 s wait before it looks for a MAVLink gimbal, on a loaded machine
MOVE_S = 30.0  # a target reached by the simulated camera (12.7 deg/s on the C12), under load
TOLERANCE_DEG = 1.0
PARAMS = """\
FRAME_CLASS 1
FRAME_TYPE 1
MNT1_TYPE 6
SERIAL2_PROTOCOL 2
MAV1_EXTRA1 10
MAV1_POSITION 5
"""


def _free_port(kind: int = socket.SOCK_STREAM) -> int:
    with socket.socket(socket.AF_INET, kind) as s:
        s.bind(("127.0.0.1", 0))
        return int(s.getsockname()[1])


def _free_instance() -> int:
    """A SITL instance number whose fixed UDP ports (RC input 5501 + 10 * instance) are free, so
    that a SITL started by someone else on this machine does not collide with ours."""
    for instance in range(7, 60):
        with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as s:
            try:
                s.bind(("127.0.0.1", 5501 + 10 * instance))
            except OSError:
                continue
            return instance
    raise RuntimeError("no free SITL instance")


def _wrap180(deg: float) -> float:
    return (deg + 180.0) % 360.0 - 180.0


def _offset(p: Position, bearing_deg: float, distance_m: float, dalt_m: float) -> Position:
    """A place `distance_m` away on `bearing_deg` (flat earth: fine over 150 m)."""
    r = 6_371_000.0
    b = math.radians(bearing_deg)
    lat = p.lat_deg + math.degrees(distance_m * math.cos(b) / r)
    lon = p.lon_deg + math.degrees(distance_m * math.sin(b) / (r * math.cos(math.radians(p.lat_deg))))
    return Position(lat, lon, p.alt_m + dalt_m)


class Gcs:
    """A ground station on the autopilot's SERIAL0 (TCP). SITL writes a text banner on that port
    and mixes more text in later: the parser is robust (garbage becomes BAD_DATA, skipped)."""

    def __init__(self, reader: asyncio.StreamReader, writer: asyncio.StreamWriter) -> None:
        self.reader, self.writer = reader, writer
        self.mav = ml.MAVLink(None, srcSystem=255, srcComponent=190)
        self.mav.robust_parsing = True
        self.texts: list[tuple[float, str]] = []
        self.acks: list[tuple[float, Any]] = []
        self.params: dict[str, float] = {}
        self.attitude: Any = None
        self.position: Any = None
        self.bad = 0
        self._tasks = [asyncio.ensure_future(self._read()), asyncio.ensure_future(self._heartbeat())]

    async def _read(self) -> None:
        while True:
            data = await self.reader.read(65536)
            if not data:
                return
            for m in self.mav.parse_buffer(data) or []:
                kind = m.get_type()
                if kind == "BAD_DATA":
                    self.bad += 1
                elif m.get_srcSystem() != AUTOPILOT[0]:
                    continue
                elif kind == "STATUSTEXT":
                    self.texts.append((time.monotonic(), m.text))
                elif kind == "COMMAND_ACK" and m.target_system == 255:
                    self.acks.append((time.monotonic(), m))
                elif kind == "PARAM_VALUE":
                    self.params[m.param_id] = m.param_value
                elif kind == "ATTITUDE" and m.get_srcComponent() == AUTOPILOT[1]:
                    self.attitude = m
                elif kind == "GLOBAL_POSITION_INT" and m.get_srcComponent() == AUTOPILOT[1]:
                    self.position = m

    async def _heartbeat(self) -> None:
        while True:
            self.send(ml.MAVLink_heartbeat_message(ml.MAV_TYPE_GCS, ml.MAV_AUTOPILOT_INVALID, 0, 0, 0, 3))
            await asyncio.sleep(1.0)

    def send(self, msg: Any) -> None:
        self.writer.write(msg.pack(self.mav))

    async def close(self) -> None:
        for t in self._tasks:
            t.cancel()
        for t in self._tasks:
            with contextlib.suppress(BaseException):
                await t
        self.writer.close()

    @property
    def heading_deg(self) -> float:
        assert self.attitude is not None, "no ATTITUDE from the autopilot"
        return math.degrees(self.attitude.yaw)

    @property
    def place(self) -> Position:
        p = self.position
        assert p is not None, "no GLOBAL_POSITION_INT from the autopilot"
        return Position(p.lat / 1e7, p.lon / 1e7, p.alt / 1000.0)

    def texts_since(self, t: float, needle: str) -> list[str]:
        return [text for (when, text) in self.texts if when >= t and needle in text]

    async def command(self, command: int, *params: float, as_int: bool = False, frame: int = 0) -> Any:
        """Send a command to the autopilot and return its final COMMAND_ACK."""
        p = [*params, *[0.0] * (7 - len(params))]
        sent = time.monotonic()
        if as_int:
            self.send(ml.MAVLink_command_int_message(*AUTOPILOT, frame, command, 0, 0, p[0], p[1], p[2], p[3],
                                                     int(p[4]), int(p[5]), p[6]))  # fmt: skip
        else:
            self.send(ml.MAVLink_command_long_message(*AUTOPILOT, command, 0, *p))

        def final() -> Any:
            return next((m for (t, m) in self.acks if t >= sent and m.command == command and m.result != 5), None)

        await until(lambda: final() is not None, 15.0, f"the autopilot's COMMAND_ACK for command {command}")
        return final()

    async def param(self, name: str) -> float:
        self.params.pop(name, None)
        self.send(ml.MAVLink_param_request_read_message(*AUTOPILOT, name.encode(), -1))
        await until(lambda: name in self.params, 15.0, f"PARAM_VALUE {name}")
        return self.params[name]


async def _connect(proc: asyncio.subprocess.Process, base: int) -> Gcs:
    deadline = time.monotonic() + 60
    while True:
        try:
            return Gcs(*await asyncio.open_connection("127.0.0.1", base))
        except OSError:
            assert proc.returncode is None, f"SITL exited with {proc.returncode}"
            assert time.monotonic() < deadline, "SITL did not open its MAVLink port within 60 s"
            await asyncio.sleep(0.5)


async def until(check: Callable[[], bool], deadline_s: float, what: str) -> float:
    """Wait (by the clock, not by a number of reads) until `check()` holds; the seconds it took."""
    start = time.monotonic()
    while not check():
        if time.monotonic() - start > deadline_s:
            raise AssertionError(f"{what}: not within {deadline_s:g} s")
        await asyncio.sleep(0.05)
    return time.monotonic() - start


@pytest.mark.skipif(
    not SITL, reason="ARDUPILOT_SITL is not set to an arducopter SITL binary: the MNT1_TYPE=6 test cannot run"
)
async def test_ardupilot_drives_the_gimbal_and_camera(rig_factory: Any) -> None:
    assert SITL is not None and Path(SITL).is_file(), f"ARDUPILOT_SITL={SITL!r} is not a file"
    work = Path(tempfile.mkdtemp(prefix="sitl-"))
    (work / "gimbal.parm").write_text(PARAMS)
    log_path = work / "sitl.log"
    # The bridge: a tcpin link for the autopilot's SERIAL2 (SITL connects as a TCP client).
    r = await rig_factory("C12", role="device", endpoints=["udpin:127.0.0.1:0", "tcpin:127.0.0.1:0"])
    _, bridge_port = r.bridge.addresses[1]
    heard: list[str] = []  # commands the bridge got from the autopilot, for the failure report
    r.bridge.node.subscribe(
        lambda m: (
            heard.append(f"{m.get_type()} {m.command} to {m.target_component} p1 {m.param1:g}")
            if m.get_type() in ("COMMAND_LONG", "COMMAND_INT") and m.get_srcSystem() == AUTOPILOT[0]
            else None
        )
    )
    instance = _free_instance()

    async def start(base: int, *extra: str) -> asyncio.subprocess.Process:
        with open(log_path, "ab") as out:
            return await asyncio.create_subprocess_exec(
                SITL, "--model", "quad", "--speedup", "1", "--defaults", str(work / "gimbal.parm"),
                "-I", str(instance), "--base-port", str(base), *extra,
                cwd=work, stdout=out, stderr=asyncio.subprocess.STDOUT,
            )  # fmt: skip

    # CAM1_TYPE from a defaults file does not stick: at boot ArduPilot converts its pre-4.4 camera
    # parameters unless CAM1_TYPE and CAM2_TYPE are *configured* (saved). So a first, short run
    # saves them (eeprom.bin in the work directory), then the real run boots with them.
    base = _free_port()
    proc = await start(base)
    try:
        setup = await _connect(proc, base)
        for name in ("CAM1_TYPE", "CAM2_TYPE"):
            setup.send(ml.MAVLink_param_set_message(*AUTOPILOT, name.encode(), 6, ml.MAV_PARAM_TYPE_INT8))
            await until(lambda n=name: setup.params.get(n) == 6, 15, f"{name} saved")  # type: ignore[misc]
        await asyncio.sleep(4.0)  # the parameter store is written in the background
        await setup.close()
    finally:
        proc.terminate()
        await proc.wait()
    base = _free_port()
    proc = await start(base, "--serial2", f"tcpclient:127.0.0.1:{bridge_port}")
    gcs: Gcs | None = None
    times: dict[str, float] = {}
    acks: list[tuple[str, str]] = []
    try:
        gcs = await _connect(proc, base)
        await steps(gcs, r, times, acks)
    except BaseException:
        with contextlib.suppress(OSError):
            tail = log_path.read_bytes()[-4000:].decode("utf-8", "replace")
            print(f"--- SITL output ({log_path}), last 4000 bytes ---\n{tail}")
        if gcs is not None:
            print("--- the autopilot's STATUSTEXTs ---\n" + "\n".join(t for _, t in gcs.texts))
        print("--- commands the bridge got from the autopilot ---\n" + "\n".join(heard[-30:]))
        print("--- the bridge's command results ---", r.bridge.dispatcher.counts)
        raise
    finally:
        print("times (s):", ", ".join(f"{k} {v:.1f}" for k, v in times.items()))
        print("acks:", "; ".join(f"{k}: {v}" for k, v in acks))
        if gcs is not None:
            await gcs.close()
        if proc.returncode is None:
            proc.terminate()
        with contextlib.suppress(Exception):
            await asyncio.wait_for(proc.wait(), 10)
        if proc.returncode is None:
            proc.kill()


async def steps(gcs: Gcs, r: Any, times: dict[str, float], acks: list[tuple[str, str]]) -> None:
    sim = r.sim
    model = get_model("C12")[1]
    started = time.monotonic()

    def accepted(what: str, ack: Any) -> None:
        name = ml.enums["MAV_RESULT"][ack.result].name
        acks.append((what, name))
        assert ack.result == ml.MAV_RESULT_ACCEPTED, f"{what}: the autopilot answered {name}"

    def at(yaw_deg: Callable[[], float], pitch_deg: float) -> Callable[[], bool]:
        g = sim.gimbal
        return lambda: (
            abs(_wrap180(g.yaw_deg - yaw_deg())) < TOLERANCE_DEG and abs(g.pitch_deg - pitch_deg) < TOLERANCE_DEG
        )

    async def move(what: str, ack: Any, check: Callable[[], bool]) -> None:
        """Send a command (the coroutine `ack`), expect ACCEPTED, then the camera at the target:
        the time from sending to reaching it is recorded."""
        t0 = time.monotonic()
        accepted(what, await ack)
        await until(check, MOVE_S, what)
        times[what] = time.monotonic() - t0

    # 1. The autopilot finds the gimbal and takes its limits from GIMBAL_DEVICE_INFORMATION.
    def found() -> list[str]:
        return [t for _, t in gcs.texts if t.startswith("Mount: ")]

    times["Mount: text after start"] = await until(lambda: bool(found()), BOOT_S, '"Mount:" from the autopilot')
    assert "SkyDroid C12" in found()[0], found()
    for name, want in (("MNT1_PITCH_MIN", model.pitch_range_deg[0]), ("MNT1_PITCH_MAX", model.pitch_range_deg[1]),
                       ("MNT1_YAW_MIN", model.yaw_range_deg[0]), ("MNT1_YAW_MAX", model.yaw_range_deg[1])):  # fmt: skip
        got = await gcs.param(name)
        assert abs(got - want) < 0.01, f"{name} {got}: expected {want} from GIMBAL_DEVICE_INFORMATION"
    # our own view of the vehicle (to compute where the camera must point), whatever the stream
    # rate parameters of this ArduPilot version are called (MAV1_* since 4.6, SR0_* before)
    for msgid in (ml.MAVLINK_MSG_ID_ATTITUDE, ml.MAVLINK_MSG_ID_GLOBAL_POSITION_INT):
        accepted(
            f"SET_MESSAGE_INTERVAL {msgid} 10 Hz", await gcs.command(ml.MAV_CMD_SET_MESSAGE_INTERVAL, msgid, 100_000)
        )
    await until(lambda: gcs.attitude is not None and gcs.position is not None, 30, "ATTITUDE and position")
    await until(lambda: r.bridge.vehicles.attitude_deg() is not None, 30, "AUTOPILOT_STATE_FOR_GIMBAL_DEVICE")
    nan = math.nan

    # 2. Body frame: DO_MOUNT_CONTROL (pitch, roll, yaw, ..., mode) and DO_GIMBAL_MANAGER_PITCHYAW.
    await move("body DO_MOUNT_CONTROL pitch -30 yaw 20",
               gcs.command(ml.MAV_CMD_DO_MOUNT_CONTROL, -30, 0, 20, 0, 0, 0, ml.MAV_MOUNT_MODE_MAVLINK_TARGETING),
               at(lambda: 20, -30))  # fmt: skip
    assert r.bridge.device.set_attitude_received > 0
    # the mount is healthy now: no "Mount: not healthy" when the autopilot runs its pre-arm checks
    t_checks = time.monotonic()
    accepted("RUN_PREARM_CHECKS, camera alive", await gcs.command(ml.MAV_CMD_RUN_PREARM_CHECKS))
    await asyncio.sleep(2.0)
    assert not gcs.texts_since(t_checks, "Mount"), gcs.texts_since(t_checks, "Mount")
    await move("body DO_GIMBAL_MANAGER_PITCHYAW pitch -10 yaw -25",
               gcs.command(ml.MAV_CMD_DO_GIMBAL_MANAGER_PITCHYAW, -10, -25, nan, nan, 0, 0, 0),
               at(lambda: -25, -10))  # fmt: skip
    # beyond the limits the autopilot took from us: clamped to the C12's +-45 deg tilt
    await move("body DO_MOUNT_CONTROL pitch -80 (limit -45)",
               gcs.command(ml.MAV_CMD_DO_MOUNT_CONTROL, -80, 0, 0, 0, 0, 0, ml.MAV_MOUNT_MODE_MAVLINK_TARGETING),
               at(lambda: 0, model.pitch_range_deg[0]))  # fmt: skip

    # 3. Earth frame, yaw locked: yaw from North; the camera turns to it minus the vehicle heading.
    earth_yaw = _wrap180(round(gcs.heading_deg) + 40)
    await move(f"earth YAW_LOCK PITCHYAW pitch -20 yaw {earth_yaw:g} (heading + 40)",
               gcs.command(ml.MAV_CMD_DO_GIMBAL_MANAGER_PITCHYAW, -20, earth_yaw, nan, nan,
                           ml.GIMBAL_MANAGER_FLAGS_YAW_LOCK, 0, 0),
               at(lambda: earth_yaw - gcs.heading_deg, -20))  # fmt: skip
    assert r.bridge.pointer.yaw_dropped == 0

    # 4. ROI location, 150 m away 30 deg left of the heading, 40 m below: the autopilot computes
    #    an earth-frame yaw and a pitch; we compute what the camera must show from what it reports.
    roi = _offset(gcs.place, gcs.heading_deg - 30, 150.0, -40.0)

    def roi_angles() -> tuple[float, float]:
        return look_at(gcs.place, gcs.heading_deg, roi)

    want_yaw, want_pitch = roi_angles()
    assert abs(want_yaw + 30) < 1 and abs(want_pitch + math.degrees(math.atan2(40, 150))) < 1
    await move("earth DO_SET_ROI_LOCATION (COMMAND_INT) yaw -30 pitch -14.9",
               gcs.command(ml.MAV_CMD_DO_SET_ROI_LOCATION, 0, 0, 0, 0, int(roi.lat_deg * 1e7),
                           int(roi.lon_deg * 1e7), roi.alt_m, as_int=True, frame=ml.MAV_FRAME_GLOBAL),
               lambda: at(lambda: roi_angles()[0], roi_angles()[1])())  # fmt: skip

    # 5. A photo through the autopilot (CAM1_TYPE 6 sends IMAGE_START_CAPTURE to our camera).
    # IMAGE_START_CAPTURE rather than DO_DIGICAM_CONTROL: ArduPilot answers the latter ACCEPTED
    # whether or not a picture was triggered, the former FAILED when its camera could not.
    before = sim.camera.photos_taken
    await move("photo: IMAGE_START_CAPTURE (camera 1, 1 image)",
               gcs.command(ml.MAV_CMD_IMAGE_START_CAPTURE, 1, 0, 1, 0, 0, 0, 0),
               lambda: sim.camera.photos_taken == before + 1)  # fmt: skip
    await asyncio.sleep(1.0)
    assert sim.camera.photos_taken == before + 1, "one command, one photo"

    # 6. The camera dies: the bridge reports COMMS_ERROR, the autopilot calls the mount unhealthy.
    await sim.stop()
    t_dead = time.monotonic()
    while True:
        accepted("RUN_PREARM_CHECKS, camera dead", await gcs.command(ml.MAV_CMD_RUN_PREARM_CHECKS))
        await asyncio.sleep(1.0)
        if gcs.texts_since(t_dead, "PreArm: Mount: not healthy"):
            break
        assert time.monotonic() - t_dead < 30, 'no "PreArm: Mount: not healthy" within 30 s of the camera dying'
    times['"PreArm: Mount: not healthy" after the camera died'] = time.monotonic() - t_dead
    times["whole run"] = time.monotonic() - started
