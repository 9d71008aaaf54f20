"""Acknowledgements that say what the camera did: a photo sent before the camera went quiet,
COMMAND_INT vs COMMAND_LONG retransmission keys, and a peer that rebooted (issue 22)."""

from __future__ import annotations

import asyncio
import random
from typing import Any

import pytest
from pymavlink.dialects.v20 import common as ml

from topgimbal.autopilot.reboots import RebootWatch
from topgimbal.clock import monotonic
from topgimbal.sim.faults import FaultInjector, FaultPlan

from .conftest import eventually
from .virtual import HealthLog, camera_input, in_virtual_time

pytestmark = pytest.mark.loopback

CAMERA = 100
PHOTO = ml.MAV_CMD_IMAGE_START_CAPTURE


def silence_camera_replies(sim: Any, seconds: float) -> None:
    """From now on, for `seconds`, nothing comes out of the simulated camera; what it is sent it
    still carries out (the simulator's own fault injector, outbound direction only)."""
    now = sim.clock.now()
    sim._fault_out = FaultInjector(FaultPlan(silence=((0.0, seconds),), direction="out"), "out", random.Random(0), now)


async def test_photo_sent_before_the_camera_went_quiet_is_not_reported_as_not_sent(rig_factory: Any) -> None:
    # The photo request's own timeout (3 s) is longer than --silence (0.6 s): the client declares
    # the link lost while our frame is at the camera, which takes the photo.
    r = await rig_factory("C12", silence_s=0.6, timeout_s=3.0)
    s, p = r.sim, r.peer
    await eventually(lambda: r.bridge.cam.answering, 10, "camera answering")
    silence_camera_replies(s, 4.0)
    ack = await p.ack(CAMERA, PHOTO, 0, 0, 1, 0, timeout=15)
    assert s.camera.photos_taken == 1, "the camera took the photo"
    assert ack.result == ml.MAV_RESULT_FAILED  # not confirmed: never ACCEPTED
    assert ack.result_param2 == 2, f"result_param2 {ack.result_param2}: sent, outcome unknown (not 3, not sent)"
    # while the link is down, a new command is really not sent: 3
    assert not r.bridge.cam.answering
    ack = await p.ack(CAMERA, PHOTO, 0, 0, 1, 0)
    assert (ack.result, ack.result_param2) == (ml.MAV_RESULT_FAILED, 3)
    assert s.camera.photos_taken == 1


async def test_command_int_is_not_a_retransmission_of_a_command_long(rig: Any) -> None:
    s, p = rig.sim, rig.peer
    assert (await p.ack(CAMERA, PHOTO, 0, 0, 1, 0)).result == ml.MAV_RESULT_ACCEPTED
    assert s.camera.photos_taken == 1
    # the same parameters in a COMMAND_INT: another sender path, another order
    assert (await p.ack(CAMERA, PHOTO, 0, 0, 1, 0, as_int=True)).result == ml.MAV_RESULT_ACCEPTED
    assert s.camera.photos_taken == 2
    # a COMMAND_INT repeated unchanged within the window is its retransmission (no confirmation field)
    assert (await p.ack(CAMERA, PHOTO, 0, 0, 1, 0, as_int=True)).result == ml.MAV_RESULT_ACCEPTED
    assert s.camera.photos_taken == 2
    # COMMAND_LONG: confirmation 0 is a first transmission (a new photo), > 0 a retransmission
    assert (await p.ack(CAMERA, PHOTO, 0, 0, 1, 0)).result == ml.MAV_RESULT_ACCEPTED
    assert s.camera.photos_taken == 3
    assert (await p.ack(CAMERA, PHOTO, 0, 0, 1, 0, confirmation=1)).result == ml.MAV_RESULT_ACCEPTED
    assert (await p.ack(CAMERA, PHOTO, 0, 0, 1, 0, confirmation=2)).result == ml.MAV_RESULT_ACCEPTED
    assert s.camera.photos_taken == 3


async def test_capture_sequence_is_forgotten_when_the_sender_reboots(rig: Any) -> None:
    s, p = rig.sim, rig.peer
    p.send(ml.MAVLink_system_time_message(0, 600_000))
    assert (await p.ack(CAMERA, PHOTO, 0, 0, 1, 1)).result == ml.MAV_RESULT_ACCEPTED
    assert s.camera.photos_taken == 1
    assert (await p.ack(CAMERA, PHOTO, 0, 0, 1, 1)).result == ml.MAV_RESULT_ACCEPTED
    assert s.camera.photos_taken == 1, "the same sequence number again: already taken"
    # the autopilot reboots: its boot clock starts again and its capture count restarts at 1
    p.send(ml.MAVLink_system_time_message(0, 4_000))
    await eventually(lambda: rig.bridge.reboots.reboots == 1, 5, "reboot noticed")
    assert (await p.ack(CAMERA, PHOTO, 0, 0, 1, 1)).result == ml.MAV_RESULT_ACCEPTED
    assert s.camera.photos_taken == 2, "the first photo after the reboot is taken"


def _from(sysid: int, compid: int, msg: Any) -> Any:
    msg.pack(ml.MAVLink(None, srcSystem=sysid, srcComponent=compid))  # sets the sender in its header
    return msg


def _heartbeat(sysid: int, compid: int = 1) -> Any:
    return _from(sysid, compid, ml.MAVLink_heartbeat_message(2, 3, 0, 0, 4, 3))


def _system_time(sysid: int, boot_ms: int) -> Any:
    return _from(sysid, 1, ml.MAVLink_system_time_message(0, boot_ms))


@pytest.mark.virtual
def test_reboot_watch_heartbeat_gap_and_boot_clock() -> None:
    seen: list[int] = []
    w = RebootWatch(lambda sysid, why: seen.append(sysid), gap_s=5.0)
    for t in (0.0, 1.0, 2.0, 6.9):  # a 4.9 s gap: a link hiccup, not a reboot
        w.on_message(_heartbeat(1), t)
    assert seen == []
    w.on_message(_heartbeat(1), 12.5)
    assert seen == [1]
    w.on_message(_heartbeat(2, 100), 12.6)
    w.on_message(_system_time(2, 50_000), 13.0)
    w.on_message(_system_time(2, 49_500), 13.1)  # reordered on the way: not a reboot
    assert seen == [1]
    w.on_message(_system_time(2, 1_200), 14.0)
    assert seen == [1, 2]


@pytest.mark.virtual
@in_virtual_time
async def test_virtual_photo_outcome_unknown_when_the_link_is_declared_lost_first(vrig_maker: Any) -> None:
    """The same in virtual time, with the timers that decide it checked: the photo goes out once
    (never retried), the link is declared lost silence_s after the camera's last frame, and the
    FAILED / 2 ack comes then, not when the photo's own timeout (3 s) would have ended."""
    silence_s, timeout_s = 0.6, 3.0
    vrig = await vrig_maker("C12", silence_s=silence_s, timeout_s=timeout_s, retries=2)
    s, p = vrig.sim, vrig.peer
    health = HealthLog(vrig.bridge)
    await eventually(lambda: vrig.bridge.cam.answering, 10, "camera answering")
    sent = camera_input(s)
    t_quiet = monotonic()
    silence_camera_replies(s, 4.0)
    acks: list[tuple[float, Any]] = []
    ack = await p.ack(CAMERA, PHOTO, 0, 0, 1, 0, timeout=15)
    acks.append((monotonic(), ack))
    assert s.camera.photos_taken == 1, "the camera took the photo"
    assert (ack.result, ack.result_param2) == (ml.MAV_RESULT_FAILED, 2)  # sent, outcome unknown
    down = health.when(False, t_quiet)
    assert down is not None and silence_s - 0.02 <= down - t_quiet <= silence_s + 0.02, down - t_quiet
    assert acks[0][0] == pytest.approx(down, abs=0.05), "answered when the link was declared lost"
    assert [data[6:10] for _, data in sent].count(b"wCAP") == 1, "a photo is never sent twice"
    # while the link is down, a new photo is really not sent: 3, at once
    t = monotonic()
    ack = await p.ack(CAMERA, PHOTO, 0, 0, 1, 0)
    assert (ack.result, ack.result_param2) == (ml.MAV_RESULT_FAILED, 3) and monotonic() - t < 0.05
    assert [data[6:10] for _, data in sent].count(b"wCAP") == 1 and s.camera.photos_taken == 1
    # the camera answers again after its 4 s: the link comes back by itself, a photo is confirmed
    await eventually(lambda: vrig.bridge.cam.answering, 10, "camera answering again")
    assert (await p.ack(CAMERA, PHOTO, 0, 0, 1, 0)).result == ml.MAV_RESULT_ACCEPTED
    assert s.camera.photos_taken == 2


@pytest.mark.virtual
@in_virtual_time
async def test_virtual_a_command_that_never_ends_is_in_progress_then_failed_at_its_timeout(vrig_maker: Any) -> None:
    """The dispatcher's own timers at their real values (commands.py: IN_PROGRESS after 0.25 s and
    every second, the whole command bounded by 30 s): a handler that never returns is reported in
    progress on that schedule, then FAILED with BRIDGE_ERROR (4) once the 30 s are up, and cancelled."""
    vrig = await vrig_maker("C12", stream_hz=5.0, attitude_hz=1.0)
    d = vrig.bridge.dispatcher
    cancelled: list[bool] = []

    async def stuck(cmd: Any) -> None:
        try:
            await asyncio.sleep(3600.0)
        except asyncio.CancelledError:
            cancelled.append(True)
            raise

    d._handlers[(CAMERA, ml.MAV_CMD_SET_CAMERA_ZOOM)] = stuck
    acks: list[tuple[float, Any]] = []
    p = vrig.peer
    inner = p._got

    def got(m: Any) -> None:
        if m.get_type() == "COMMAND_ACK" and m.command == ml.MAV_CMD_SET_CAMERA_ZOOM:
            acks.append((monotonic(), m))
        inner(m)

    p._got = got  # type: ignore[method-assign]
    t0 = monotonic()
    p.command(CAMERA, ml.MAV_CMD_SET_CAMERA_ZOOM, 1, 0.5)
    await eventually(lambda: bool(acks) and acks[-1][1].result != ml.MAV_RESULT_IN_PROGRESS, 60, "a final ack")
    progress = [t - t0 for t, m in acks if m.result == ml.MAV_RESULT_IN_PROGRESS]
    want = [d.progress_after_s + k * d.progress_every_s for k in range(100)]
    want = [t for t in want if t < d.timeout_s]
    assert progress == pytest.approx(want, abs=0.01)
    t_final, final = acks[-1]
    assert (final.result, final.result_param2) == (ml.MAV_RESULT_FAILED, 4)
    # decided at the first progress tick past the deadline: never before timeout_s, at most a tick after
    assert d.timeout_s <= t_final - t0 <= d.timeout_s + d.progress_every_s
    assert cancelled == [True] and d.limits.in_use == 0
