"""The simulator's truth (`sim --truth FILE`): JSON lines at a fixed rate (50 Hz by default) with
the time, each target's true bearing / elevation and picture position, the gimbal's earth-frame
attitude, the zoom, and the camera tracker's state and box. Benchmarks and tests score against it.

One line (keys are stable; numbers rounded to 1e-4 degree / 1e-5 of the picture):

    {"t": 1.24, "wall": 1790000000.123, "yaw_deg": 3.2, "pitch_deg": -4.9, "roll_deg": 0.0,
     "vehicle_deg": [30.0, 0.0, 0.0], "zoom_x": 1.0, "hfov_deg": 56.0, "tracking": "tracking", "box": [0.51, 0.5, 0.027, 0.048],
     "targets": [{"name": "t1", "bearing_deg": 3.4, "elevation_deg": -5.0, "visible": true,
                  "x": 0.503, "y": 0.5}]}

`t` is device time since power-on (the targets' clock); `vehicle_deg` the vehicle's yaw, pitch and
roll as the host fed them (sim/world.py: the camera's earth-frame attitude includes them); `box` is the tracker's (centre x, y,
width, height, fractions of the picture) or null; a target's `x`, `y` are null when it is behind
the camera.
"""

from __future__ import annotations

import asyncio
import contextlib
import json
import logging
from pathlib import Path
from typing import IO, TYPE_CHECKING, Any

from ..clock import monotonic, wall_time
from .tracker import project
from .world import pose_of

if TYPE_CHECKING:
    from .device import Device

log = logging.getLogger("topgimbal.sim")

TRUTH_HZ = 50.0
MAX_TRUTH_HZ = 1000.0


def truth_record(device: Device, wall_s: float | None = None) -> dict[str, Any]:
    """The truth now (call on the simulator's thread: it brings the physics up to now)."""
    device.sync()
    state = device.state
    now = device.now
    pose = pose_of(state.gimbal, state.position)  # the one the picture and the laser read
    yaw, pitch, roll = pose.yaw_deg, pose.pitch_deg, pose.roll_deg
    hfov = state.tracking_hfov_deg()
    targets = []
    for tv in state.target_views(now):
        pos = project(yaw, pitch, tv.bearing_deg, tv.elevation_deg, hfov)
        targets.append(
            {
                "name": tv.name,
                "bearing_deg": round(tv.bearing_deg, 4),
                "elevation_deg": round(tv.elevation_deg, 4),
                "visible": tv.visible,
                "x": None if pos is None else round(pos[0], 5),
                "y": None if pos is None else round(pos[1], 5),
            }
        )
    tracker = state.tracker
    box = tracker.box if tracker is not None and tracker.state == "tracking" else None
    return {
        "t": round(now - state.camera.booted_at, 4),
        "wall": round(wall_time() if wall_s is None else wall_s, 4),
        "yaw_deg": round(yaw, 4),
        "pitch_deg": round(pitch, 4),
        "roll_deg": round(roll, 4),
        "vehicle_deg": [round(v, 4) for v in pose.vehicle],
        "zoom_x": state.camera.zoom_x,
        "hfov_deg": round(hfov, 4),
        "tracking": state.camera.tracking,
        "box": None if box is None else [round(v, 5) for v in box],
        "targets": targets,
    }


class TruthWriter:
    """Writes the truth of a device to a file while running (on the simulator's event loop)."""

    def __init__(self, device: Device, path: str | Path, rate_hz: float = TRUTH_HZ) -> None:
        if not 1.0 <= rate_hz <= MAX_TRUTH_HZ:
            raise ValueError(f"truth rate must be within 1..{MAX_TRUTH_HZ:g} Hz (got {rate_hz:g})")
        self.device = device
        self.path = Path(path)
        self.period_s = 1.0 / rate_hz
        self.lines = 0
        self._file: IO[str] | None = None
        self._task: asyncio.Task[None] | None = None

    async def start(self) -> None:
        self._file = self.path.open("w", encoding="utf-8")
        self._task = asyncio.create_task(self._run())
        log.info("truth: writing %s at %.0f Hz", self.path, 1.0 / self.period_s)

    async def _run(self) -> None:
        assert self._file is not None
        due = monotonic()
        while True:
            try:
                self._file.write(json.dumps(truth_record(self.device), separators=(",", ":")) + "\n")
                self._file.flush()
            except OSError as exc:  # a full disk ends the truth, not the simulator
                log.warning("truth: cannot write %s (%s); no more truth is written", self.path, exc.strerror or exc)
                return
            self.lines += 1
            due += self.period_s
            await asyncio.sleep(max(0.0, due - monotonic()))

    async def stop(self) -> None:
        if self._task is not None:
            self._task.cancel()
            with contextlib.suppress(asyncio.CancelledError):
                await self._task
            self._task = None
        if self._file is not None:
            self._file.close()
            self._file = None
