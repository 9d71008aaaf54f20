"""Gimbal protocol v2 through the bridge, pymavlink as the peer, the simulator as the camera."""

from __future__ import annotations

import math
from typing import Any

import pytest
from pymavlink.dialects.v20 import common as ml

from topgimbal.clock import monotonic
from topgimbal.mavlink.quaternion import from_euler_deg, to_euler_deg
from topgimbal.protocol import get_model

from .conftest import NAN, eventually
from .virtual import HealthLog, camera_input, in_virtual_time, silence_replies

pytestmark = pytest.mark.loopback

GIMBAL, CAMERA, THERMAL = 154, 100, 101
COMMS_ERROR = ml.GIMBAL_DEVICE_ERROR_FLAGS_COMMS_ERROR


async def test_heartbeats_and_device_information(rig) -> None:
    p = rig.peer
    hb = await p.wait("HEARTBEAT", lambda m: m.get_srcComponent() == GIMBAL)
    assert hb.type == ml.MAV_TYPE_GIMBAL and hb.autopilot == ml.MAV_AUTOPILOT_INVALID
    cam = await p.wait("HEARTBEAT", lambda m: m.get_srcComponent() == CAMERA)
    assert cam.type == ml.MAV_TYPE_CAMERA
    await p.wait("HEARTBEAT", lambda m: m.get_srcComponent() == THERMAL)  # the C12's thermal lens
    info = await p.request(GIMBAL, 283, "GIMBAL_DEVICE_INFORMATION")
    assert info.vendor_name == "SkyDroid" and info.model_name == "C12"
    assert math.isclose(info.yaw_max, math.radians(90), rel_tol=1e-6)
    # the C12's tilt range from its profile (+-45 deg on real units, errata), not a copy of it
    assert math.isclose(info.pitch_min, math.radians(get_model("C12")[1].pitch_range_deg[0]), rel_tol=1e-6)
    assert info.pitch_min > math.radians(-90)
    caps = info.cap_flags
    for flag in ("HAS_NEUTRAL", "HAS_PITCH_AXIS", "HAS_YAW_AXIS", "HAS_YAW_FOLLOW", "HAS_YAW_LOCK", "HAS_ROLL_AXIS"):
        assert caps & getattr(ml, f"GIMBAL_DEVICE_CAP_FLAGS_{flag}"), flag
    assert not caps & ml.GIMBAL_DEVICE_CAP_FLAGS_SUPPORTS_YAW_IN_EARTH_FRAME  # SkyDroid has no GI* commands
    assert info.gimbal_device_id == 0
    assert info.firmware_version == 1 | 5 << 8 | 2 << 16  # the simulated C12 answers VER 010502


async def test_sip_limits_and_earth_frame_flag(rig_factory) -> None:
    r = await rig_factory("SIP")
    info = await r.peer.request(GIMBAL, 283, "GIMBAL_DEVICE_INFORMATION")
    assert math.isclose(math.degrees(info.yaw_max), 150, rel_tol=1e-5)
    assert info.cap_flags & ml.GIMBAL_DEVICE_CAP_FLAGS_SUPPORTS_YAW_IN_EARTH_FRAME
    assert info.vendor_name == "TOPOTEK"


async def test_attitude_status_is_the_simulators_attitude(rig) -> None:
    s, p = rig.sim, rig.peer
    s.gimbal.angle("yaw", 25.0)
    s.gimbal.angle("pitch", -30.0)
    await eventually(lambda: abs(s.gimbal.yaw_deg - 25) < 0.01 and abs(s.gimbal.pitch_deg + 30) < 0.01)
    # both axes: a status sent while the pitch was still settling is not the one to check (seen under load)
    st = await p.wait(
        "GIMBAL_DEVICE_ATTITUDE_STATUS",
        lambda m: abs(to_euler_deg(m.q).yaw_deg - 25) < 0.05 and abs(to_euler_deg(m.q).pitch_deg + 30) < 0.05,
    )
    e = to_euler_deg(st.q)
    assert abs(e.pitch_deg + 30) < 0.05 and abs(e.roll_deg) < 0.05
    assert st.gimbal_device_id == 0 and st.get_srcComponent() == GIMBAL
    assert st.flags & ml.GIMBAL_DEVICE_FLAGS_YAW_IN_VEHICLE_FRAME
    assert st.failure_flags == 0
    assert abs(st.angular_velocity_z) < 0.01  # standing still


async def test_angular_velocity_while_turning(rig) -> None:
    rig.sim.gimbal.rate("yaw", 8.0)
    st = await rig.peer.wait(
        "GIMBAL_DEVICE_ATTITUDE_STATUS", lambda m: abs(math.degrees(m.angular_velocity_z) - 8) < 1.5
    )
    assert abs(math.degrees(st.angular_velocity_y)) < 1.5


async def test_device_set_attitude_angle_and_rate_forms(rig) -> None:
    s, p = rig.sim, rig.peer
    q = from_euler_deg(0, -20, 15)
    flags = (
        ml.GIMBAL_DEVICE_FLAGS_ROLL_LOCK
        | ml.GIMBAL_DEVICE_FLAGS_PITCH_LOCK
        | ml.GIMBAL_DEVICE_FLAGS_YAW_IN_VEHICLE_FRAME
    )
    for _ in range(5):  # autopilots stream set-points; repeats are dropped, not queued
        p.send(ml.MAVLink_gimbal_device_set_attitude_message(1, GIMBAL, flags, list(q), NAN, NAN, NAN))
    await eventually(lambda: abs(s.gimbal.yaw_deg - 15) < 0.05 and abs(s.gimbal.pitch_deg + 20) < 0.05, 10)
    p.send(ml.MAVLink_gimbal_device_set_attitude_message(1, GIMBAL, flags, [NAN] * 4, 0.0, 0.0, math.radians(-5)))
    await eventually(lambda: s.gimbal.yaw_deg < 14.0, what="yaw turning at -5 deg/s")
    p.send(ml.MAVLink_gimbal_device_set_attitude_message(1, GIMBAL, flags, [NAN] * 4, 0.0, 0.0, 0.0))
    await eventually(lambda: not s.gimbal.moving)


async def test_yaw_lock_flag_sets_the_cameras_lock_mode(rig) -> None:
    s, p = rig.sim, rig.peer
    flags = ml.GIMBAL_DEVICE_FLAGS_YAW_LOCK | ml.GIMBAL_DEVICE_FLAGS_YAW_IN_VEHICLE_FRAME
    p.send(
        ml.MAVLink_gimbal_device_set_attitude_message(1, GIMBAL, flags, list(from_euler_deg(0, 0, 5)), NAN, NAN, NAN)
    )
    await eventually(lambda: s.gimbal.mode == "lock")
    st = await p.wait("GIMBAL_DEVICE_ATTITUDE_STATUS", lambda m: m.flags & ml.GIMBAL_DEVICE_FLAGS_YAW_LOCK)
    assert st.flags & ml.GIMBAL_DEVICE_FLAGS_YAW_IN_VEHICLE_FRAME
    p.send(ml.MAVLink_gimbal_device_set_attitude_message(1, GIMBAL, 32, list(from_euler_deg(0, 0, 5)), NAN, NAN, NAN))
    await eventually(lambda: s.gimbal.mode == "follow")


async def test_earth_frame_yaw_uses_the_vehicle_heading(rig) -> None:
    s, p = rig.sim, rig.peer
    autopilot = type(p)(sysid=1, compid=1)
    await autopilot.connect(rig.bridge.addresses[0][1])
    try:
        autopilot.send(ml.MAVLink_attitude_message(0, 0.0, 0.0, math.radians(40), 0, 0, 0))
        flags = ml.GIMBAL_DEVICE_FLAGS_YAW_IN_EARTH_FRAME
        p.send(
            ml.MAVLink_gimbal_device_set_attitude_message(
                1, GIMBAL, flags, list(from_euler_deg(0, 0, 60)), NAN, NAN, NAN
            )
        )
        await eventually(lambda: abs(s.gimbal.yaw_deg - 20) < 0.05, 10, "body yaw 60 - 40 = 20")
    finally:
        autopilot.close()


async def test_manager_information_status_and_pitchyaw(rig) -> None:
    s, p = rig.sim, rig.peer
    info = await p.request(GIMBAL, 280, "GIMBAL_MANAGER_INFORMATION")
    assert info.gimbal_device_id == GIMBAL  # role both: the device is this very component
    assert info.cap_flags & ml.GIMBAL_MANAGER_CAP_FLAGS_CAN_POINT_LOCATION_GLOBAL
    ack = await p.ack(GIMBAL, ml.MAV_CMD_DO_GIMBAL_MANAGER_PITCHYAW, -35, 20, NAN, NAN, 0, 0, 0)
    assert ack.result == ml.MAV_RESULT_ACCEPTED
    assert any(f.ident == "GAM" for f in s.received)  # acked after the camera's echo of the angle command
    await eventually(lambda: abs(s.gimbal.yaw_deg - 20) < 0.05 and abs(s.gimbal.pitch_deg + 35) < 0.05, 10)
    ack = await p.ack(GIMBAL, ml.MAV_CMD_DO_GIMBAL_MANAGER_PITCHYAW, NAN, NAN, 0, 6, 0, 0, 0, as_int=True)
    assert ack.result == ml.MAV_RESULT_ACCEPTED
    await eventually(lambda: s.gimbal.yaw_deg > 21, what="yaw rate 6 deg/s")
    assert (
        await p.ack(GIMBAL, ml.MAV_CMD_DO_GIMBAL_MANAGER_PITCHYAW, NAN, NAN, NAN, NAN)
    ).result == ml.MAV_RESULT_DENIED
    # out of the C12's range: denied before anything is sent
    assert (await p.ack(GIMBAL, ml.MAV_CMD_DO_GIMBAL_MANAGER_PITCHYAW, 0, 120)).result == ml.MAV_RESULT_DENIED
    st = await p.wait("GIMBAL_MANAGER_STATUS")
    assert st.gimbal_device_id == GIMBAL and st.primary_control_sysid == 0


async def test_manager_configure_gives_control_to_one_sender(rig) -> None:
    p = rig.peer
    ack = await p.ack(GIMBAL, ml.MAV_CMD_DO_GIMBAL_MANAGER_CONFIGURE, -2, -2, -1, -1, 0, 0, 0)
    assert ack.result == ml.MAV_RESULT_ACCEPTED
    st = await p.wait("GIMBAL_MANAGER_STATUS", lambda m: m.primary_control_sysid == 255)
    assert st.primary_control_compid == 190
    other = type(p)(sysid=254, compid=190)
    await other.connect(rig.bridge.addresses[0][1])
    try:
        ack = await other.ack(GIMBAL, ml.MAV_CMD_DO_GIMBAL_MANAGER_PITCHYAW, -10, 0)
        assert ack.result == ml.MAV_RESULT_DENIED
        assert (await p.ack(GIMBAL, ml.MAV_CMD_DO_GIMBAL_MANAGER_PITCHYAW, -10, 0)).result == ml.MAV_RESULT_ACCEPTED
        await p.ack(GIMBAL, ml.MAV_CMD_DO_GIMBAL_MANAGER_CONFIGURE, -3, -3, -1, -1)
        assert (await other.ack(GIMBAL, ml.MAV_CMD_DO_GIMBAL_MANAGER_PITCHYAW, -12, 0)).result == ml.MAV_RESULT_ACCEPTED
    finally:
        other.close()


async def test_manager_set_attitude_and_set_pitchyaw_streams(rig) -> None:
    s, p = rig.sim, rig.peer
    p.send(
        ml.MAVLink_gimbal_manager_set_attitude_message(1, GIMBAL, 0, 0, list(from_euler_deg(0, 10, -25)), NAN, NAN, NAN)
    )
    await eventually(lambda: abs(s.gimbal.yaw_deg + 25) < 0.05 and abs(s.gimbal.pitch_deg - 10) < 0.05, 10)
    p.send(
        ml.MAVLink_gimbal_manager_set_pitchyaw_message(1, GIMBAL, 0, 0, math.radians(-15), math.radians(5), NAN, NAN)
    )
    await eventually(lambda: abs(s.gimbal.yaw_deg - 5) < 0.05 and abs(s.gimbal.pitch_deg + 15) < 0.05, 10)


async def test_manager_only_role_speaks_for_a_non_mavlink_device(rig_factory) -> None:
    r = await rig_factory("C12", role="manager")
    info = await r.peer.request(GIMBAL, 280, "GIMBAL_MANAGER_INFORMATION")
    assert info.gimbal_device_id == 1
    st = await r.peer.wait("GIMBAL_DEVICE_ATTITUDE_STATUS")
    assert st.gimbal_device_id == 1
    dev = await r.peer.request(GIMBAL, 283, "GIMBAL_DEVICE_INFORMATION")
    assert dev.gimbal_device_id == 1


async def test_device_only_role_has_no_manager(rig_factory) -> None:
    r = await rig_factory("C12", role="device")
    ack = await r.peer.ack(GIMBAL, 512, 280)
    assert ack.result == ml.MAV_RESULT_UNSUPPORTED
    ack = await r.peer.ack(GIMBAL, ml.MAV_CMD_DO_GIMBAL_MANAGER_PITCHYAW, -10, 0)
    assert ack.result == ml.MAV_RESULT_UNSUPPORTED


async def test_roi_location_needs_and_uses_the_vehicle_position(rig) -> None:
    s, p = rig.sim, rig.peer
    lat, lon = 47.397742, 8.545594
    ack = await p.ack(GIMBAL, ml.MAV_CMD_DO_SET_ROI_LOCATION, 0, 0, 0, 0, lat + 0.001, lon, 400.0)
    assert ack.result == ml.MAV_RESULT_TEMPORARILY_REJECTED  # no GLOBAL_POSITION_INT heard yet
    autopilot = type(p)(sysid=1, compid=1)
    await autopilot.connect(rig.bridge.addresses[0][1])
    try:
        # 111 m north, 100 m below the vehicle, vehicle heading 0: yaw 0, pitch ~ -42 deg
        autopilot.send(ml.MAVLink_attitude_message(0, 0.0, 0.0, 0.0, 0, 0, 0))
        autopilot.send(
            ml.MAVLink_global_position_int_message(0, int(lat * 1e7), int(lon * 1e7), 500000, 100000, 0, 0, 0, 0)
        )
        ack = await p.ack(GIMBAL, ml.MAV_CMD_DO_SET_ROI_LOCATION, 0, 0, 0, 0, lat + 0.001, lon, 400.0)
        assert ack.result == ml.MAV_RESULT_ACCEPTED
        expected_pitch = -math.degrees(math.atan2(100.0, math.radians(0.001) * 6371008.8))
        await eventually(lambda: abs(s.gimbal.pitch_deg - expected_pitch) < 0.1 and abs(s.gimbal.yaw_deg) < 0.1, 15)
        # the vehicle turns right by 30 deg: the gimbal turns left to keep the place in view
        for _ in range(3):
            autopilot.send(ml.MAVLink_attitude_message(0, 0.0, 0.0, math.radians(30), 0, 0, 0))
            autopilot.send(
                ml.MAVLink_global_position_int_message(0, int(lat * 1e7), int(lon * 1e7), 500000, 100000, 0, 0, 0, 3000)
            )
        await eventually(lambda: abs(s.gimbal.yaw_deg + 30) < 0.2, 15)
        assert (await p.ack(GIMBAL, ml.MAV_CMD_DO_SET_ROI_NONE)).result == ml.MAV_RESULT_ACCEPTED
        assert rig.bridge.manager.roi is None
    finally:
        autopilot.close()


async def test_camera_that_stops_answering_and_comes_back(rig_factory) -> None:
    from topgimbal.sim import Simulator

    r = await rig_factory("C12", silence=True)
    p = r.peer
    port = r.sim.addresses["udp"][0][1]
    await r.sim.stop()
    st = await p.wait(
        "GIMBAL_DEVICE_ATTITUDE_STATUS", lambda m: m.failure_flags & ml.GIMBAL_DEVICE_ERROR_FLAGS_COMMS_ERROR
    )
    assert st.get_srcComponent() == GIMBAL
    # The client says the link is down: commands fail at once (nothing is sent), result_param2 3.
    ack = await p.ack(GIMBAL, ml.MAV_CMD_DO_GIMBAL_MANAGER_PITCHYAW, -10, 5)
    assert ack.result == ml.MAV_RESULT_FAILED and ack.result_param2 == 3
    # the text may come in MAVLink 2 chunks (more than 50 bytes): read it whole
    await eventually(lambda: "link down" in "".join(m.text for m in p.messages if m.get_type() == "STATUSTEXT"))
    assert all(m.severity == 3 for m in p.messages if m.get_type() == "STATUSTEXT")
    assert r.bridge.cam.client is not None and not r.bridge.cam.client.connected
    sim2 = Simulator("C12")
    await sim2.start(udp=[("127.0.0.1", port)])
    r.sim = sim2  # the fixture stops it
    await p.wait("GIMBAL_DEVICE_ATTITUDE_STATUS", lambda m: (m.failure_flags & 128) == 0, timeout=10)
    # Back (the client's link is up again, and it restarted the attitude stream by itself): the
    # very same command is confirmed at the first try. Nothing was sent while the link was down,
    # so no earlier identical request can be waiting to take this one's answer.
    ack = await p.ack(GIMBAL, ml.MAV_CMD_DO_GIMBAL_MANAGER_PITCHYAW, -10, 5)
    assert ack.result == ml.MAV_RESULT_ACCEPTED
    assert r.bridge.cam.link_changes >= 2  # down, then up: the client's own events
    await eventually(lambda: abs(sim2.gimbal.pitch_deg + 10) < 0.05, 10)


@pytest.mark.virtual
@pytest.mark.parametrize("silence_s", [0.6, 3.0])
@in_virtual_time
async def test_virtual_camera_that_stops_answering_and_comes_back(vrig_maker: Any, silence_s: float) -> None:
    """The same in virtual time, the camera silent rather than gone (a datagram link: nothing
    closes): declared down exactly silence_s after its last frame, nothing sent while down, back
    as soon as its answers come again (the client's ping), the stream resumed by the client."""
    vrig = await vrig_maker("C12", silence_s=silence_s, timeout_s=1.0, retries=2)
    p = vrig.peer
    health = HealthLog(vrig.bridge)
    await eventually(lambda: vrig.bridge.cam.answering, 10, "camera answering")
    sent = camera_input(vrig.sim)
    quiet_s = 10.0
    t_quiet = monotonic()
    silence_replies(vrig.sim, quiet_s)
    await p.wait("GIMBAL_DEVICE_ATTITUDE_STATUS", lambda m: m.failure_flags & COMMS_ERROR, timeout=silence_s + 5)
    down = health.when(False, t_quiet)
    # the last frame came at most one stream period (50 Hz) before the silence began
    assert down is not None and silence_s - 0.02 <= down - t_quiet <= silence_s + 0.02, down - t_quiet
    ack = await p.ack(GIMBAL, ml.MAV_CMD_DO_GIMBAL_MANAGER_PITCHYAW, -10, 5)
    assert (ack.result, ack.result_param2) == (ml.MAV_RESULT_FAILED, 3)
    await eventually(lambda: "link down" in "".join(m.text for m in p.messages if m.get_type() == "STATUSTEXT"))
    await p.wait("GIMBAL_DEVICE_ATTITUDE_STATUS", lambda m: not m.failure_flags & COMMS_ERROR, timeout=quiet_s + 10)
    up = health.when(True, down)
    # back with the first answer after the window: the client pings a quiet stream every ping_after_s (1 s)
    assert up is not None and t_quiet + quiet_s <= up <= t_quiet + quiet_s + 1.0 + 0.05, up - t_quiet
    assert [u for t, u in health.changes if t >= t_quiet] == [False, True]
    t_cmd = monotonic()
    ack = await p.ack(GIMBAL, ml.MAV_CMD_DO_GIMBAL_MANAGER_PITCHYAW, -10, 5)
    assert ack.result == ml.MAV_RESULT_ACCEPTED  # at the first try
    await eventually(lambda: abs(vrig.sim.gimbal.pitch_deg + 10) < 0.05, 10)
    # the command's frame (SkyDroid GAM) went out now, once, and never while the link was down
    idents = [(t, data[7:10]) for t, data in sent]
    assert [i for t, i in idents if t >= t_cmd].count(b"GAM") == 1
    assert b"GAM" not in {i for t, i in idents if t < t_cmd}
