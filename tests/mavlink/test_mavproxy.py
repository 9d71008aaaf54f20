"""MAVProxy 1.8.75 (its `camera` module, a client no one here wrote) against the bridge and the
simulator, headless: discovery, the definition, params, a palette set, the image source, the
thermal range and the recording status. The simulator's state is the truth for every change."""

from __future__ import annotations

import asyncio
import math
import os
import re
import signal
import sys
from pathlib import Path
from typing import Any

import pytest
from pymavlink import mavutil

from waiting import until

from .conftest import Rig, eventually

pytestmark = [pytest.mark.external, pytest.mark.integration]
MAVPROXY = Path(sys.executable).with_name("mavproxy.py")  # installed by `make .venv/.installed`


class MAVProxy:
    def __init__(self, proc: asyncio.subprocess.Process) -> None:
        self.proc = proc
        self.lines: list[str] = []
        self.task = asyncio.ensure_future(self._read())

    async def _read(self) -> None:
        assert self.proc.stdout is not None
        while line := await self.proc.stdout.readline():
            self.lines.append(line.decode("utf-8", "replace").rstrip())

    async def command(self, text: str, expect: str, timeout: float = 20.0) -> str:
        """Type a command; the first output line after it matching `expect` (a regex)."""
        start = len(self.lines)
        self.lines.append(f">>> {text}")
        assert self.proc.stdin is not None
        self.proc.stdin.write(text.encode() + b"\n")
        await self.proc.stdin.drain()
        return await self.wait(expect, start, timeout)

    async def ask_until(self, text: str, expect: str, bound_s: float = 60.0, every_s: float = 2.0) -> str:
        """Type a command again every `every_s` until an answer to it matches `expect`: for what
        MAVProxy shows of a state it learns from a message (a PARAM_EXT_ACK, a reloaded setting),
        which a loaded machine may have it process after the command was answered once."""
        deadline = asyncio.get_running_loop().time() + bound_s
        while True:
            try:
                return await self.command(text, expect, timeout=every_s)
            except AssertionError:
                if asyncio.get_running_loop().time() >= deadline:
                    raise

    async def wait(self, expect: str, start: int = 0, timeout: float = 20.0) -> str:
        pattern = re.compile(expect)
        found: list[str] = []

        def seen() -> bool:
            found[:] = [ln for ln in self.lines[start:] if pattern.search(ln)]
            return bool(found)

        try:
            await eventually(seen, timeout, f"MAVProxy printing {expect!r}")
        except AssertionError as exc:
            raise AssertionError(f"{exc}; it printed:\n" + "\n".join(self.lines)) from None
        return found[0]

    async def close(self) -> None:
        if self.proc.returncode is None:
            self.proc.send_signal(signal.SIGTERM)
            try:
                await asyncio.wait_for(self.proc.wait(), 10)
            except asyncio.TimeoutError:
                self.proc.kill()
                await self.proc.wait()
        self.task.cancel()


def _read_tlog(path: Path) -> tuple[list[float], list[int]]:
    """From a MAVProxy telemetry log (complete or still being written): the CAMERA_THERMAL_RANGE
    maxima and the recording times of CAMERA_CAPTURE_STATUS while recording, in order."""
    thermal: list[float] = []
    rec_ms: list[int] = []
    if not path.exists():
        return thermal, rec_ms
    log = mavutil.mavlink_connection(str(path))
    try:
        while (m := log.recv_match(type=["CAMERA_THERMAL_RANGE", "CAMERA_CAPTURE_STATUS"])) is not None:
            if m.get_type() == "CAMERA_THERMAL_RANGE":
                thermal.append(m.max)
            elif m.video_status == 1:
                rec_ms.append(m.recording_time_ms)
    finally:
        log.close()
    return thermal, rec_ms


def _time_goes_on(rec_ms: list[int]) -> bool:
    return len(rec_ms) >= 2 and rec_ms[-1] > rec_ms[0]


async def start_mavproxy(port: int, workdir: Path, modules: str = "camera") -> MAVProxy:
    proc = await asyncio.create_subprocess_exec(
        str(MAVPROXY), f"--master=udpout:127.0.0.1:{port}", "--mav20", f"--default-modules={modules}",
        f"--state-basedir={workdir}", "--source-system=255",
        # the vehicle's system: an autopilot's heartbeat would select it; the bridge alone sends none
        # (MAVProxy passes other systems' messages only to multi-vehicle modules: camera, not ftp)
        "--target-system=1",
        stdin=asyncio.subprocess.PIPE, stdout=asyncio.subprocess.PIPE, stderr=asyncio.subprocess.STDOUT,
        cwd=workdir, env={**os.environ, "PYTHONUNBUFFERED": "1", "DISPLAY": ""},
    )  # fmt: skip
    # MAVProxy writes its telemetry log through a buffer it flushes only with `flushlogs` set: the
    # test reads the log while MAVProxy runs, and a SIGTERM lost what was still buffered
    assert proc.stdin is not None
    proc.stdin.write(b"set flushlogs 1\n")
    return MAVProxy(proc)


async def test_mavproxy_camera_module_drives_a_sip(rig_factory: Any, tmp_path: Path) -> None:
    rig: Rig = await rig_factory("SIP", silence_s=3.0, timeout_s=1.0)
    mp = await start_mavproxy(rig.bridge.addresses[0][1], tmp_path)  # type: ignore[index]
    try:
        await mp.wait(r"SIP thermal \(1:101\): loaded 2 settings", timeout=60)
        await mp.wait(r"SIP \(1:100\): loaded 8 settings")
        assert "SIP thermal (1:101)" in await mp.command("camera status", r"SIP thermal \(1:101\) streams=")
        await mp.command("camera select 1:101", r"Selected camera .*1:101")
        info = await mp.command("camera info", r"definition: http://127\.0\.0\.1:\d+/sip-thermal\.xml")
        assert "version" in info
        rig.sim.settings["IMG"]["palette"] = "arctic"  # changed behind MAVProxy's back
        await mp.command("camera definition", r"1:101\): loaded 2 settings")  # reloads and reads every setting
        await mp.ask_until("camera params", r"IMG_PALETTE\s+5\b")  # the camera's value (arctic = 05)
        start = len(mp.lines)
        mp.lines.append(">>> camera param IMG_PALETTE 4")
        assert mp.proc.stdin is not None
        mp.proc.stdin.write(b"camera param IMG_PALETTE 4\n")
        await eventually(lambda: rig.sim.settings["IMG"]["palette"] == "medical", 20, "the palette set")
        assert await rig.bridge.cam.call(lambda c: c.palette()) == "medical"  # read back over TOP
        # MAVProxy shows the new value once it has the bridge's PARAM_EXT_ACK ("[pending]" before):
        # at load 11 that came after one `camera params` had printed the old value (a fresh-clone run)
        await mp.ask_until("camera params", r"IMG_PALETTE\s+4\b(?!.*pending)")
        assert not any("error" in ln.lower() for ln in mp.lines[start:])
        await mp.command("camera source thermal", r"SET_CAMERA_SOURCE: ACCEPTED")
        assert rig.sim.settings["PIP"]["mode"] == "sub_only"
        await mp.command("camera source rgb", r"SET_CAMERA_SOURCE: ACCEPTED")
        assert rig.sim.settings["PIP"]["mode"] == "main_only"
        await mp.command("camera select 1:100", r"Selected camera .*1:100")
        await mp.command("camera record start", r"VIDEO_START_CAPTURE: ACCEPTED")
        assert rig.sim.camera.recording

        # MAVProxy's discover asks for CAMERA_CAPTURE_STATUS: ask until MAVProxy's own telemetry log
        # holds two recording times, the time going on. Counting what the bridge sent was not enough:
        # MAVProxy's tlog lost what its buffer still held when it was stopped (one recording time in
        # the tlog, two sent: the flake this replaces, twice; start_mavproxy now sets flushlogs)
        tlog = tmp_path / "mav.tlog"
        for _ in range(10):
            await mp.command("camera discover", r"discovery requested")
            await asyncio.sleep(1.0)
            if len(set(_read_tlog(tlog)[1])) >= 2:
                break
        await until("two recording times in MAVProxy's tlog", lambda: _read_tlog(tlog)[1], _time_goes_on, bound_s=20)
        await mp.command("camera info", r"recording=yes")
        await mp.command("camera record stop", r"VIDEO_STOP_CAPTURE: ACCEPTED")
        assert not rig.sim.camera.recording
    finally:
        await mp.close()
    # What MAVProxy received (its telemetry log): the thermal range it asked for, the recording time.
    thermal, rec_ms = _read_tlog(tmp_path / "mav.tlog")
    summary = (f"tlog: {len(thermal)} CAMERA_THERMAL_RANGE (max {thermal[-1] if thermal else None} degC), "
               f"recording_time_ms while recording: {rec_ms}")  # fmt: skip
    mp.lines.append(summary)
    transcript = os.environ.get("TOPGIMBAL_MAVPROXY_TRANSCRIPT")
    if transcript:  # a session to show (the closing note)
        Path(transcript).write_text("\n".join(mp.lines) + "\n", encoding="utf-8")
    assert thermal and all(math.isfinite(t) for t in thermal), summary
    assert _time_goes_on(rec_ms), summary
