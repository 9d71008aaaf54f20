"""What the bridge core is made of, made from its config: the gimbal component (device and, by
role, manager) and the camera components (one per lens, each with its video URLs and, with
`video_out`, the RTP push it advertises). Bridge.__init__ (bridge.py) calls these and wires them."""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

from ..autopilot.vehicle import Vehicles
from ..outputs.rtp_out import RtpPush, advertised, parse_targets
from .bridge_config import BridgeConfig, BridgeConfigError
from .camera import CameraComponent
from .camera_link import CameraLink
from .commands import Dispatcher
from .gimbal_device import GimbalDevice
from .gimbal_manager import GimbalManager
from .node import Node
from .pointing import Pointer
from .services import Services

MAV_TYPE_GIMBAL, MAV_TYPE_CAMERA = 26, 30
NON_MAVLINK_GIMBAL_ID = 1


@dataclass
class Gimbal:
    services: Services
    device: GimbalDevice
    manager: GimbalManager | None


@dataclass
class Cameras:
    services: list[Services] = field(default_factory=list)
    cameras: list[CameraComponent] = field(default_factory=list)
    pushes: list[RtpPush] = field(default_factory=list)


def build_gimbal(
    c: BridgeConfig, node: Node, dispatcher: Dispatcher, cam: CameraLink, pointer: Pointer, vehicles: Vehicles,
    identity: dict[str, Any],
) -> Gimbal:  # fmt: skip
    """The gimbal component: its device (id 0 when it is one, or the non-MAVLink gimbal's id behind
    a manager) and, in the manager and both roles, its manager."""
    svc = Services(node.component(c.compid, "gimbal"), dispatcher, MAV_TYPE_GIMBAL)
    device_id = 0 if c.role in ("device", "both") else NON_MAVLINK_GIMBAL_ID
    device = GimbalDevice(
        svc, cam, pointer, attitude_hz=c.attitude_hz, gimbal_device_id=device_id,
        accept_set_attitude=c.role != "manager", identity=identity,
    )  # fmt: skip
    manager = None
    if c.role in ("manager", "both"):
        managed = c.compid if c.role == "both" else NON_MAVLINK_GIMBAL_ID
        manager = GimbalManager(svc, cam, pointer, vehicles, gimbal_device_id=managed)
    return Gimbal(svc, device, manager)


def build_cameras(
    c: BridgeConfig, node: Node, dispatcher: Dispatcher, cam: CameraLink, vehicles: Vehicles, identity: dict[str, Any]
) -> Cameras:
    """One camera component per lens (the thermal one where the model has it and `thermal`), each
    announcing its lens's stream (`video_urls` given: the first to the visible camera, the second to
    the thermal one) and, where `video_out` pushes that lens, the RTP target too."""
    out = Cameras()
    pushed = parse_targets(c.video_out)
    if pushed and c.camera_compid is None:
        raise BridgeConfigError("video_out needs the camera components (they advertise it); camera_compid is None")
    if c.camera_compid is not None:
        gimbal_ref = c.compid if c.role in ("device", "both") else NON_MAVLINK_GIMBAL_ID
        lenses = ["visible"] + (["thermal"] if c.thermal and cam.profile.thermal else [])
        by_lens = cam.profile.rtsp_urls(cam.camera_host, port=c.video_port)
        for i, lens in enumerate(lenses):
            svc = Services(node.component(c.camera_compid + i, f"camera-{lens}"), dispatcher, MAV_TYPE_CAMERA)
            out.services.append(svc)
            if c.video_urls is not None:
                urls = c.video_urls
                mine = urls if len(lenses) == 1 else urls[i : i + 1] if i < len(urls) else []
            else:
                mine = [by_lens[lens]] if lens in by_lens else []
            if lens in pushed:
                if not mine:
                    raise BridgeConfigError(f"video_out: the {lens} lens has no RTSP stream to push (give video_urls)")
                out.pushes.append(RtpPush(mine[0], pushed.pop(lens), name=lens))
                mine = [*mine, advertised(out.pushes[-1].target_url)]
            out.cameras.append(CameraComponent(
                svc, cam, vehicles, lens=lens, gimbal_device_id=gimbal_ref, video_urls=mine, identity=identity,
                range_hz=c.range_hz, media_url=c.media_url, companion_tracking=c.companion_tracking))  # fmt: skip
    if pushed:
        raise BridgeConfigError(f"video_out: no {', '.join(pushed)} camera on this bridge ({cam.profile.model})")
    return out
