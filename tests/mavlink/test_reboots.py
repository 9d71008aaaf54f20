"""The first photo after an autopilot reboot (issue 32, item 2): ArduPilot numbers its captures
from 1 again after each boot; the bridge notices the reboot from what an autopilot always sends its
gimbal (AUTOPILOT_STATE_FOR_GIMBAL_DEVICE's boot time going back) or from its connection closing and
coming back, and deduplicates a capture sequence number only within the retransmission window,
with a log line whenever a request takes no new photo."""

from __future__ import annotations

import asyncio
import logging
from typing import Any

import pytest
from pymavlink.dialects.v20 import common as ml

from topgimbal.autopilot.reboots import RebootWatch
from topgimbal.clock import monotonic
from topgimbal.mavlink import camera_photos
from topgimbal.mavlink import commands as commands_module

from .conftest import NAN, Peer, eventually
from .virtual import in_virtual_time

pytestmark = pytest.mark.external

CAMERA = 100


def state(boot_s: float, sysid: int = 1) -> Any:
    mav = ml.MAVLink(None, srcSystem=sysid, srcComponent=1)
    m = ml.MAVLink_autopilot_state_for_gimbal_device_message(
        1, 154, int(boot_s * 1e6), [1.0, 0.0, 0.0, 0.0], 0, NAN, NAN, NAN, 0, NAN, 0, 0, NAN
    )
    m.pack(mav)  # sets the source ids
    return m


def test_a_boot_clock_going_back_in_autopilot_state_is_a_reboot() -> None:
    seen: list[tuple[int, str]] = []
    w = RebootWatch(lambda sysid, why: seen.append((sysid, why)))
    for t in (100.0, 100.02, 100.01, 100.04):  # a reordered datagram is not a reboot
        w.on_message(state(t), 0.0)
    assert seen == []
    w.on_message(state(2.5), 10.0)
    assert [s for s, _ in seen] == [1] and "went back" in seen[0][1]
    w.on_message(state(2.52, sysid=2), 10.0)  # another system's clock is its own
    assert len(seen) == 1
    # another sign of the same reboot (SYSTEM_TIME going back too) is not a second reboot
    mav = ml.MAVLink(None, srcSystem=1, srcComponent=1)
    for boot_ms, now in ((90_000, 10.5), (1_000, 11.0)):
        t = ml.MAVLink_system_time_message(0, boot_ms)
        t.pack(mav)
        w.on_message(t, now)
    assert len(seen) == 1 and w.reboots == 1
    w.on_message(state(1.0), 30.0)  # a later reboot is one
    assert len(seen) == 2


def test_a_connection_that_closed_and_came_back_is_a_reboot() -> None:
    seen: list[int] = []
    w = RebootWatch(lambda sysid, why: seen.append(sysid))
    m = state(10.0)
    m._topgimbal_link_peer = ("tcpin:127.0.0.1:5760", ("127.0.0.1", 40000))  # type: ignore[attr-defined]
    w.on_message(m, 0.0)
    w.on_peer_gone(("tcpin:127.0.0.1:5760", ("127.0.0.1", 40001)))  # someone else's connection
    w.on_message(m, 0.0)
    assert seen == []
    w.on_peer_gone(("tcpin:127.0.0.1:5760", ("127.0.0.1", 40000)))
    assert seen == []  # not until it is heard again
    w.on_message(m, 0.0)
    assert seen == [1]
    w.on_message(m, 0.0)
    assert seen == [1]


async def test_the_first_photo_after_a_reboot_is_taken(rig_factory: Any, caplog: Any) -> None:
    r = await rig_factory("C12")
    caplog.set_level(logging.INFO, logger="topgimbal.mavlink")
    autopilot = await Peer(sysid=1, compid=1).connect(r.bridge.addresses[0][1])
    cam = r.sim.camera
    try:
        autopilot.send(state(100.0))
        before = cam.photos_taken
        ack = await autopilot.ack(CAMERA, ml.MAV_CMD_IMAGE_START_CAPTURE, 0, 0, 1, 1)
        assert ack.result == ml.MAV_RESULT_ACCEPTED and cam.photos_taken == before + 1
        # the autopilot reboots (a few seconds, under the heartbeat gap) and counts from 1 again
        autopilot.send(state(3.0))
        await eventually(lambda: r.bridge.reboots.reboots == 1, 5, "the reboot noticed")
        ack = await autopilot.ack(CAMERA, ml.MAV_CMD_IMAGE_START_CAPTURE, 0, 0, 1, 1)
        assert ack.result == ml.MAV_RESULT_ACCEPTED
        assert cam.photos_taken == before + 2, "the first photo after the reboot was dropped"
        assert any("rebooted" in rec.getMessage() for rec in caplog.records)
    finally:
        autopilot.close()


async def test_a_capture_sequence_is_deduplicated_only_within_the_window(
    rig_factory: Any, caplog: Any, monkeypatch: Any
) -> None:
    monkeypatch.setattr(camera_photos, "RETRANSMIT_WINDOW_S", 0.5)
    monkeypatch.setattr(commands_module, "RETRANSMIT_WINDOW_S", 0.5)
    r = await rig_factory("C12")
    caplog.set_level(logging.INFO, logger="topgimbal.mavlink")
    gcs, cam = r.peer, r.sim.camera
    before = cam.photos_taken
    ack = await gcs.ack(CAMERA, ml.MAV_CMD_IMAGE_START_CAPTURE, 0, 0, 1, 7)
    assert ack.result == ml.MAV_RESULT_ACCEPTED and cam.photos_taken == before + 1
    # the same sequence number at once, as COMMAND_INT (not a retransmission of the same message
    # for the dispatcher): the photo taken answers it, and the log says so
    ack = await gcs.ack(CAMERA, ml.MAV_CMD_IMAGE_START_CAPTURE, 0, 0, 1, 7, as_int=True)
    assert ack.result == ml.MAV_RESULT_ACCEPTED and cam.photos_taken == before + 1
    assert any("capture sequence 7 again" in rec.getMessage() for rec in caplog.records)
    # past the window the same number is a new photo (a sender that rebooted unnoticed)
    await asyncio.sleep(0.6)
    ack = await gcs.ack(CAMERA, ml.MAV_CMD_IMAGE_START_CAPTURE, 0, 0, 1, 7, as_int=True, frame=0)
    assert ack.result == ml.MAV_RESULT_ACCEPTED
    await eventually(lambda: cam.photos_taken == before + 2, 5, "a new photo past the window")
    assert any("a new photo" in rec.getMessage() for rec in caplog.records)


@pytest.mark.virtual
@in_virtual_time
async def test_virtual_a_capture_sequence_is_deduplicated_exactly_within_the_window(
    vrig_maker: Any, caplog: Any
) -> None:
    """The same at the product's own window (RETRANSMIT_WINDOW_S, 3 s, not shortened), either
    side of its edge: 0.1 s inside it the number is the photo already taken, 0.1 s past it a new one."""
    window_s = commands_module.RETRANSMIT_WINDOW_S
    caplog.set_level(logging.INFO, logger="topgimbal.mavlink")
    vrig = await vrig_maker("C12", stream_hz=5.0, attitude_hz=1.0)
    gcs, cam = vrig.peer, vrig.sim.camera
    before = cam.photos_taken
    # acked once the camera confirmed the photo: the window starts at the ack (the photo's record)
    ack = await gcs.ack(CAMERA, ml.MAV_CMD_IMAGE_START_CAPTURE, 0, 0, 1, 7)
    t0 = monotonic()
    assert ack.result == ml.MAV_RESULT_ACCEPTED and cam.photos_taken == before + 1
    await asyncio.sleep(window_s - 0.1)
    ack = await gcs.ack(CAMERA, ml.MAV_CMD_IMAGE_START_CAPTURE, 0, 0, 1, 7, as_int=True)
    assert ack.result == ml.MAV_RESULT_ACCEPTED and cam.photos_taken == before + 1
    assert any("capture sequence 7 again" in rec.getMessage() for rec in caplog.records)
    await asyncio.sleep(t0 + window_s + 0.1 - monotonic())
    ack = await gcs.ack(CAMERA, ml.MAV_CMD_IMAGE_START_CAPTURE, 0, 0, 1, 7)  # COMMAND_LONG, confirmation 0
    assert ack.result == ml.MAV_RESULT_ACCEPTED
    await eventually(lambda: cam.photos_taken == before + 2, 5, "a new photo past the window")
    assert any("a new photo" in rec.getMessage() for rec in caplog.records)
