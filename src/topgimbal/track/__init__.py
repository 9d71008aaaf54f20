"""The companion tracking loop (docs/tracking.md): an OpenCV tracker on the camera's video driving
the gimbal's rates with a PI controller that compensates the video latency, for cameras without
a tracker of their own or when the user wants their own.

Layers: `control` (pure: attitude history, the PI law, ArduPilot's P-only pixel law for
comparison), `vision` (OpenCV's KCF / CSRT with a template check and re-acquisition), `loop`
(the asyncio loop over an SDK client and a picture source)."""

from __future__ import annotations

from typing import TYPE_CHECKING

from .._lazy import lazy_getattr

if TYPE_CHECKING:
    from .control import AngleController, AttitudeHistory, Gains, PixelPGains
    from .loop import CompanionTracker, Picture, TrackConfig, TrackReport, rtsp_frames
    from .vision import TrackerError, VisualTracker

_LAZY = {
    "AngleController": "control",
    "AttitudeHistory": "control",
    "Gains": "control",
    "PixelPGains": "control",
    "CompanionTracker": "loop",
    "Picture": "loop",
    "TrackConfig": "loop",
    "TrackReport": "loop",
    "rtsp_frames": "loop",
    "TrackerError": "vision",
    "VisualTracker": "vision",
}

__getattr__ = lazy_getattr(__name__, _LAZY, globals())

__all__ = [
    "AngleController",
    "AttitudeHistory",
    "CompanionTracker",
    "Gains",
    "Picture",
    "PixelPGains",
    "TrackConfig",
    "TrackReport",
    "TrackerError",
    "VisualTracker",
    "rtsp_frames",
]
