"""IMAGE_STOP_CAPTURE while an interval photo is at the camera: that photo is waited for, counted
and announced, not cancelled in flight (the camera took it; the bridge used to never say so, so
CAMERA_CAPTURE_STATUS counted one photo less and a geotag was missing). On memory links, looptime."""

from __future__ import annotations

import asyncio
import random
from typing import Any

import pytest
from pymavlink.dialects.v20 import common as ml

from topgimbal.sim import FaultPlan
from topgimbal.sim.faults import FaultInjector

from .conftest import eventually

pytestmark = pytest.mark.virtual

CAMERA = 100


async def test_a_photo_in_flight_when_the_capture_stops_is_counted_and_announced(vrig_maker: Any) -> None:
    v = await vrig_maker("C12", timeout_s=2.0, silence_s=5.0)
    cam, sim, peer = v.bridge.cameras[0], v.sim, v.peer
    # every answer of the camera 0.5 s late (less than the bridge's photo timeout): a stop sent
    # while a photo is asked reaches the bridge before the camera's answer
    sim._fault_out = FaultInjector(FaultPlan(delay_s=0.5, direction="out"), "out", random.Random(0), sim.clock.now())
    start = await peer.ack(CAMERA, ml.MAV_CMD_IMAGE_START_CAPTURE, 0, 1.0, 0, 0)  # every second until stopped
    assert start.result == ml.MAV_RESULT_ACCEPTED
    await eventually(lambda: sim.camera.photos_taken >= 2 and cam.image_status == 3, 30, "an interval photo asked")
    stop = await peer.ack(CAMERA, ml.MAV_CMD_IMAGE_STOP_CAPTURE)
    assert stop.result == ml.MAV_RESULT_ACCEPTED
    taken = sim.camera.photos_taken
    await eventually(
        lambda: len([m for m in peer.messages if m.get_type() == "CAMERA_IMAGE_CAPTURED"]) == taken,
        5,
        "every photo the camera took announced",
    )
    status = await peer.request(CAMERA, ml.MAVLINK_MSG_ID_CAMERA_CAPTURE_STATUS, "CAMERA_CAPTURE_STATUS")
    assert status.image_status == 0 and status.image_count == taken == cam.image_count
    indexes = [m.image_index for m in peer.messages if m.get_type() == "CAMERA_IMAGE_CAPTURED"]
    assert indexes == list(range(taken)) and all(
        m.capture_result == 1 for m in peer.messages if m.get_type() == "CAMERA_IMAGE_CAPTURED"
    )
    await asyncio.sleep(5.0)  # five more intervals (virtual time)
    assert sim.camera.photos_taken == taken  # and no photo after the stop
