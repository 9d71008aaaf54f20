"""A camera fleet on Zenoh: one process serves N cameras (`FleetServer`, `topgimbal zenoh`); the
key layout and the remote client are in client/remote_keys.py and client/remote.py. Needs the
`zenoh` extra (eclipse-zenoh), imported only when a session opens. See docs/fleet.md."""

from __future__ import annotations

from .camera import MAX_CALLS, ServedCamera
from .server import FleetServer
from .specs import MAX_CAMERAS, CameraSpec, parse_camera, read_camera_file

__all__ = ["MAX_CALLS", "MAX_CAMERAS", "CameraSpec", "FleetServer", "ServedCamera", "parse_camera", "read_camera_file"]
