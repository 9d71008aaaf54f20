"""What the picture depends on, read from a simulator (read-only but for `sync()`, which brings
the motors up to now exactly as any received command does), as one small immutable value that
the render thread can take without touching the simulator."""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING

from ..clock import wall_time
from ..sim.world import pose_of

if TYPE_CHECKING:
    from ..sim.device import Device


@dataclass(frozen=True)
class SceneState:
    model: str
    yaw_deg: float  # earth frame
    pitch_deg: float
    roll_deg: float
    zoom_x: float  # visible: optical x digital
    thermal_zoom_x: float
    palette: str
    osd: bool
    recording: bool
    record_s: float  # seconds since recording started
    tracking: str
    wall_s: float  # wall-clock time the state was taken (burned into the picture)
    frame: int = 0
    # Visible targets of the simulated world (sim --target): (bearing, elevation, size deg,
    # contrast 0..1, temperature °C) each; and the camera tracker's box (centre x, y, w, h).
    targets: tuple[tuple[float, float, float, float, float], ...] = ()
    track_box: tuple[float, float, float, float] | None = None


def capture(device: Device, frame: int = 0, wall_s: float | None = None) -> SceneState:
    """Take the state of a `sim.Device`. Call it on the simulator's own thread."""
    device.sync()
    g = device.gimbal
    cam = device.camera
    pose = pose_of(g, device.state.position)  # the world pose the truth and the laser read too
    yaw, pitch, roll = pose.yaw_deg, pose.pitch_deg, pose.roll_deg
    tracker = device.state.tracker
    settings = device.settings
    osd = settings.get("EXT", {}).get("osd", "on") != "off"
    dz = settings.get("DZM", {})
    tz = float(cam.thermal_digital_zoom_x or 1.0)
    if "thermal_zoom_x" not in dz:
        tz = float(cam.digital_zoom_x or 1.0)  # one digital zoom for both lenses (SkyDroid)
    return SceneState(
        model=device.model.name,
        yaw_deg=float(yaw),
        pitch_deg=float(pitch),
        roll_deg=float(roll),
        zoom_x=float(cam.optical_zoom_x * cam.digital_zoom_x),
        thermal_zoom_x=max(1.0, tz),
        palette=str(settings.get("IMG", {}).get("palette", "white_hot")),
        osd=osd,
        recording=bool(cam.recording),
        record_s=max(0.0, device.now - cam.record_started) if cam.recording else 0.0,
        tracking=str(cam.tracking),
        wall_s=wall_time() if wall_s is None else wall_s,
        frame=frame,
        targets=tuple(
            (t.bearing_deg, t.elevation_deg, t.size_deg, t.contrast, t.temp_c)
            for t in device.state.target_views(device.now)
            if t.visible
        ),
        track_box=tracker.box if tracker is not None and tracker.state == "tracking" else None,
    )
