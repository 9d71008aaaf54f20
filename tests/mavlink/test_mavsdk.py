"""MAVSDK 4.x (the native binding, no mavsdk_server) as a ground station against bridge +
simulator: gimbal discovered, set_angles reaches the target, attitude agrees with the simulator,
take_photo counted once, video start/stop, zoom. Every wait is bounded."""

from __future__ import annotations

import asyncio
from typing import Any

import pytest
from mavsdk.asyncio import ComponentType, Configuration
from mavsdk.asyncio.plugins.camera import CameraAsync
from mavsdk.asyncio.plugins.gimbal import GimbalAsync, GimbalMode, SendMode

from .conftest import eventually, keep, mavsdk_session

pytestmark = pytest.mark.external

CAMERA = 100


async def _until(agen: Any, pred: Any, timeout: float) -> Any:
    async def first() -> Any:
        async for item in agen:
            if pred(item):
                return item
        return None

    try:
        return await asyncio.wait_for(first(), timeout)
    finally:
        keep(agen)  # never closed: an unsubscribe racing MAVSDK's callbacks crashed it (conftest.keep)


@pytest.mark.cage(240)  # MAVSDK can hang its caller (conftest.mavsdk_session)
async def test_mavsdk_ground_station(rig_factory) -> None:
    r = await rig_factory("C12", timeout_s=1.0, retries=2)
    sim = r.sim
    port = r.bridge.addresses[0][1]
    cfg = Configuration.create_with_component_type(ComponentType.GROUND_STATION)
    async with mavsdk_session(cfg) as mavsdk:
        await mavsdk.add_any_connection(f"udpout://127.0.0.1:{port}")
        await eventually(lambda: mavsdk._mavsdk.system_count() > 0, 15, "MAVSDK sees the system")
        system = (await mavsdk.get_systems())[0]
        gimbal = GimbalAsync(system)
        camera = CameraAsync(system)
        keep(gimbal, camera)
        if True:
            glist = await _until(gimbal.subscribe_gimbal_list(), lambda g: len(g.gimbals) > 0, 20)
            assert glist is not None and len(glist.gimbals) == 1, "gimbal not discovered"
            item = glist.gimbals[0]
            assert item.gimbal_manager_component_id == 154 and item.gimbal_device_id == 154
            gid = item.gimbal_id

            await gimbal.set_angles(gid, 0.0, -30.0, 20.0, GimbalMode.YAW_FOLLOW, SendMode.ONCE)
            att = await _until(
                gimbal.subscribe_attitude(),
                lambda a: (
                    abs(a.euler_angle_forward.pitch_deg + 30) <= 0.5 and abs(a.euler_angle_forward.yaw_deg - 20) <= 0.5
                ),
                30,
            )
            assert att is not None, "MAVSDK never saw the target attitude"
            await eventually(lambda: abs(sim.gimbal.pitch_deg + 30) <= 0.5 and abs(sim.gimbal.yaw_deg - 20) <= 0.5, 10)
            # MAVSDK's attitude agrees with the simulator's own (the gimbal stands still now)
            att = await _until(gimbal.subscribe_attitude(), lambda a: True, 5)
            e = att.euler_angle_forward
            assert abs(e.pitch_deg - sim.gimbal.pitch_deg) < 0.1 and abs(e.yaw_deg - sim.gimbal.yaw_deg) < 0.1
            assert abs(e.roll_deg - sim.gimbal.roll_deg) < 0.1

            clist = await _until(
                camera.subscribe_camera_list(), lambda c: any(i.component_id == CAMERA for i in c.cameras), 20
            )
            assert clist is not None, "camera not discovered"
            await camera.take_photo(CAMERA)
            await eventually(lambda: sim.camera.photos_taken >= 1, 5)
            await asyncio.sleep(1.0)  # any retransmission would arrive by now
            assert sim.camera.photos_taken == 1

            await camera.start_video(CAMERA)
            assert sim.camera.recording
            await camera.stop_video(CAMERA)
            assert not sim.camera.recording

            await camera.zoom_range(CAMERA, 100.0)
            assert sim.camera.digital_zoom_x == 4.0
            await camera.zoom_range(CAMERA, 0.0)
            assert sim.camera.digital_zoom_x == 1.0
