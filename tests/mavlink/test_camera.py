"""Camera protocol v2 through the bridge, pymavlink as the peer."""

from __future__ import annotations

import asyncio
import math

import pytest
from pymavlink.dialects.v20 import common as ml

from .conftest import eventually

pytestmark = pytest.mark.loopback

CAMERA, THERMAL, GIMBAL = 100, 101, 154


def _vfov(hfov_deg: float, aspect: float) -> float:
    return math.degrees(2 * math.atan(math.tan(math.radians(hfov_deg) / 2) / aspect))


async def test_camera_information_is_true_to_the_model(rig) -> None:
    info = await rig.peer.request(CAMERA, 259, "CAMERA_INFORMATION")
    f = info.flags
    assert f & ml.CAMERA_CAP_FLAGS_CAPTURE_IMAGE and f & ml.CAMERA_CAP_FLAGS_CAPTURE_VIDEO
    assert f & ml.CAMERA_CAP_FLAGS_HAS_BASIC_ZOOM and f & ml.CAMERA_CAP_FLAGS_HAS_BASIC_FOCUS
    assert f & ml.CAMERA_CAP_FLAGS_HAS_TRACKING_POINT and not f & ml.CAMERA_CAP_FLAGS_HAS_TRACKING_RECTANGLE
    assert f & ml.CAMERA_CAP_FLAGS_HAS_VIDEO_STREAM  # the C12 profile lists its RTSP streams
    assert bytes(info.vendor_name).rstrip(b"\0") == b"SkyDroid"
    assert info.gimbal_device_id == GIMBAL
    th = await rig.peer.request(THERMAL, 259, "CAMERA_INFORMATION")
    assert bytes(th.model_name).rstrip(b"\0").endswith(b"thermal")
    assert not th.flags & ml.CAMERA_CAP_FLAGS_CAPTURE_IMAGE  # the C12's CAP has no thermal-only mode


async def test_storage_settings_and_capture_status(rig) -> None:
    s, p = rig.sim, rig.peer
    st = await p.request(CAMERA, 261, "STORAGE_INFORMATION")
    total = s.camera.sd_total_mb
    assert st.status == ml.STORAGE_STATUS_READY and st.total_capacity == total
    assert math.isclose(st.available_capacity, total - s.camera.sd_used_mb, abs_tol=1)
    s.camera.sd_present = False
    st = await p.request(CAMERA, 261, "STORAGE_INFORMATION")
    assert st.status == ml.STORAGE_STATUS_EMPTY
    settings = await p.request(CAMERA, 260, "CAMERA_SETTINGS")
    assert settings.mode_id == ml.CAMERA_MODE_IMAGE
    cs = await p.request(CAMERA, 262, "CAMERA_CAPTURE_STATUS")
    assert cs.video_status == 0 and cs.image_status == 0


async def test_single_photo_is_taken_once_even_when_retransmitted(rig) -> None:
    s, p = rig.sim, rig.peer
    ack = await p.ack(CAMERA, ml.MAV_CMD_IMAGE_START_CAPTURE, 0, 0, 1, 7)
    assert ack.result == ml.MAV_RESULT_ACCEPTED
    assert s.camera.photos_taken == 1
    img = await p.request(CAMERA, 263, "CAMERA_IMAGE_CAPTURED", param2=0)
    assert img.image_index == 0 and img.capture_result == 1
    # the ground station did not hear the ack and sends the command again (confirmation 1)
    ack = await p.ack(CAMERA, ml.MAV_CMD_IMAGE_START_CAPTURE, 0, 0, 1, 7, confirmation=1)
    assert ack.result == ml.MAV_RESULT_ACCEPTED
    # and a new command with the same capture sequence number is not a new photo either
    assert (await p.ack(CAMERA, ml.MAV_CMD_IMAGE_START_CAPTURE, 0, 0, 1, 7)).result == ml.MAV_RESULT_ACCEPTED
    assert s.camera.photos_taken == 1
    assert (await p.ack(CAMERA, ml.MAV_CMD_IMAGE_START_CAPTURE, 0, 0, 1, 8)).result == ml.MAV_RESULT_ACCEPTED
    assert s.camera.photos_taken == 2


async def test_interval_capture_and_stop(rig) -> None:
    s, p = rig.sim, rig.peer
    ack = await p.ack(CAMERA, ml.MAV_CMD_IMAGE_START_CAPTURE, 0, 0.2, 3, 0)
    assert ack.result == ml.MAV_RESULT_ACCEPTED
    await eventually(lambda: s.camera.photos_taken == 3)
    captured = [m for m in p.messages if m.get_type() == "CAMERA_IMAGE_CAPTURED"]
    await eventually(lambda: len([m for m in p.messages if m.get_type() == "CAMERA_IMAGE_CAPTURED"]) == 3)
    assert [m.image_index for m in p.messages if m.get_type() == "CAMERA_IMAGE_CAPTURED"] == [0, 1, 2]
    del captured
    ack = await p.ack(CAMERA, ml.MAV_CMD_IMAGE_START_CAPTURE, 0, 0.2, 0, 0)  # until stopped
    assert ack.result == ml.MAV_RESULT_ACCEPTED
    await eventually(lambda: s.camera.photos_taken >= 5)
    assert (await p.ack(CAMERA, ml.MAV_CMD_IMAGE_STOP_CAPTURE)).result == ml.MAV_RESULT_ACCEPTED
    n = s.camera.photos_taken
    cs = await p.request(CAMERA, 262, "CAMERA_CAPTURE_STATUS")
    assert cs.image_status == 0 and cs.image_count == n
    assert (await p.ack(CAMERA, ml.MAV_CMD_IMAGE_START_CAPTURE, 0, 0, 3, 0)).result == ml.MAV_RESULT_DENIED


async def test_video_start_stop(rig) -> None:
    s, p = rig.sim, rig.peer
    assert (await p.ack(CAMERA, ml.MAV_CMD_VIDEO_START_CAPTURE, 0, 0)).result == ml.MAV_RESULT_ACCEPTED
    assert s.camera.recording
    cs = await p.request(CAMERA, 262, "CAMERA_CAPTURE_STATUS")
    assert cs.video_status == 1
    assert (await p.ack(CAMERA, ml.MAV_CMD_VIDEO_STOP_CAPTURE)).result == ml.MAV_RESULT_ACCEPTED
    assert not s.camera.recording


async def test_zoom_range_continuous_and_focus(rig) -> None:
    s, p = rig.sim, rig.peer
    assert (await p.ack(CAMERA, ml.MAV_CMD_SET_CAMERA_ZOOM, ml.ZOOM_TYPE_RANGE, 100)).result == 0
    assert s.camera.digital_zoom_x == 4.0  # the C12: digital 1..4x
    assert (await p.ack(CAMERA, ml.MAV_CMD_SET_CAMERA_ZOOM, ml.ZOOM_TYPE_RANGE, 34)).result == 0
    assert s.camera.digital_zoom_x == 2.0
    assert (await p.ack(CAMERA, ml.MAV_CMD_SET_CAMERA_ZOOM, ml.ZOOM_TYPE_RANGE, 140)).result == ml.MAV_RESULT_DENIED
    assert (await p.ack(CAMERA, ml.MAV_CMD_SET_CAMERA_ZOOM, ml.ZOOM_TYPE_CONTINUOUS, 1)).result == 0
    zmc = [s.dialect.decode(f).fields["action"] for f in s.received if f.ident == "ZMC"]
    assert zmc == ["zoom_in"]  # the C12 has no optical zoom motor to move, but it got the command
    assert (await p.ack(CAMERA, ml.MAV_CMD_SET_CAMERA_ZOOM, ml.ZOOM_TYPE_CONTINUOUS, 0)).result == 0
    assert [s.dialect.decode(f).fields["action"] for f in s.received if f.ident == "ZMC"] == ["zoom_in", "stop"]
    assert (
        await p.ack(CAMERA, ml.MAV_CMD_SET_CAMERA_ZOOM, ml.ZOOM_TYPE_FOCAL_LENGTH, 20)
    ).result == ml.MAV_RESULT_UNSUPPORTED
    assert (await p.ack(CAMERA, ml.MAV_CMD_SET_CAMERA_FOCUS, ml.FOCUS_TYPE_CONTINUOUS, 1)).result == 0
    assert s.camera.focus_dir == 1
    assert (await p.ack(CAMERA, ml.MAV_CMD_SET_CAMERA_FOCUS, ml.FOCUS_TYPE_AUTO)).result == 0
    assert s.camera.autofocus
    assert (
        await p.ack(CAMERA, ml.MAV_CMD_SET_CAMERA_FOCUS, ml.FOCUS_TYPE_METERS, 3)
    ).result == ml.MAV_RESULT_UNSUPPORTED


async def test_tracking_point_and_stop(rig) -> None:
    s, p = rig.sim, rig.peer
    assert (await p.ack(CAMERA, ml.MAV_CMD_CAMERA_TRACK_POINT, 0.5, 0.25, 0.05)).result == 0
    assert s.camera.tracking == "tracking"
    got = [f for f in s.received if f.ident == "GOT"][-1]
    assert rig.sim.dialect.decode(got).fields == {"x_px": 640, "y_px": 180}
    status = await p.request(CAMERA, 275, "CAMERA_TRACKING_IMAGE_STATUS")
    assert status.tracking_mode == ml.CAMERA_TRACKING_MODE_POINT and math.isclose(status.point_x, 0.5)
    assert (await p.ack(CAMERA, ml.MAV_CMD_CAMERA_STOP_TRACKING)).result == 0
    assert s.camera.tracking == "stopped"
    # the C12 has no rectangle tracking: unsupported, nothing sent
    assert (
        await p.ack(CAMERA, ml.MAV_CMD_CAMERA_TRACK_RECTANGLE, 0.1, 0.1, 0.2, 0.2)
    ).result == ml.MAV_RESULT_UNSUPPORTED


async def test_legacy_requests_message_interval_and_unknown_commands(rig) -> None:
    p = rig.peer
    fut_info = asyncio.ensure_future(p.wait("CAMERA_INFORMATION", lambda m: m.get_srcComponent() == CAMERA))
    await asyncio.sleep(0)
    assert (await p.ack(CAMERA, ml.MAV_CMD_REQUEST_CAMERA_INFORMATION, 1)).result == 0
    await fut_info
    assert (await p.ack(CAMERA, ml.MAV_CMD_REQUEST_STORAGE_INFORMATION, 0, 1)).result == 0
    assert (await p.ack(CAMERA, ml.MAV_CMD_REQUEST_CAMERA_SETTINGS, 1)).result == 0
    assert (await p.ack(CAMERA, ml.MAV_CMD_REQUEST_CAMERA_CAPTURE_STATUS, 1)).result == 0
    assert (await p.ack(CAMERA, 512, 148)).result == ml.MAV_RESULT_UNSUPPORTED  # AUTOPILOT_VERSION: not ours
    assert (await p.ack(CAMERA, ml.MAV_CMD_STORAGE_FORMAT, 1, 1)).result == ml.MAV_RESULT_UNSUPPORTED
    assert (await p.ack(GIMBAL, ml.MAV_CMD_SET_MESSAGE_INTERVAL, 285, 200000)).result == 0
    mi = asyncio.ensure_future(p.wait("MESSAGE_INTERVAL"))
    await asyncio.sleep(0)
    assert (await p.ack(GIMBAL, ml.MAV_CMD_GET_MESSAGE_INTERVAL, 285)).result == 0
    assert (await mi).interval_us == 200000
    # faster than the camera streams: denied
    assert (await p.ack(GIMBAL, ml.MAV_CMD_SET_MESSAGE_INTERVAL, 285, 1000)).result == ml.MAV_RESULT_DENIED
    # PROTOCOL_VERSION is not in the common dialect pymavlink generates: unsupported, said so
    assert (await p.ack(GIMBAL, ml.MAV_CMD_REQUEST_PROTOCOL_VERSION, 1)).result == ml.MAV_RESULT_UNSUPPORTED


@pytest.mark.external
async def test_sip_streams_thermal_camera_and_rangefinder(rig_factory) -> None:
    r = await rig_factory("SIP", range_hz=0.0)
    s, p = r.sim, r.peer
    info = await p.request(CAMERA, 259, "CAMERA_INFORMATION")
    assert info.flags & ml.CAMERA_CAP_FLAGS_HAS_VIDEO_STREAM and info.flags & ml.CAMERA_CAP_FLAGS_HAS_TRACKING_RECTANGLE
    vs = await p.request(CAMERA, 269, "VIDEO_STREAM_INFORMATION")
    assert vs.uri == "rtsp://127.0.0.1:554/stream=0" and vs.type == ml.VIDEO_STREAM_TYPE_RTSP
    tvs = await p.request(THERMAL, 269, "VIDEO_STREAM_INFORMATION")
    assert tvs.uri.endswith("stream=1") and tvs.flags & ml.VIDEO_STREAM_STATUS_FLAGS_THERMAL
    before = s.camera.photos_taken
    assert (await p.ack(THERMAL, ml.MAV_CMD_IMAGE_START_CAPTURE, 0, 0, 1, 1)).result == 0
    cap = [f for f in s.received if f.ident == "CAP"][-1]
    assert s.dialect.decode(cap).fields["mode"] == "thermal" and s.camera.photos_taken == before + 1
    assert (await p.ack(THERMAL, ml.MAV_CMD_SET_CAMERA_ZOOM, ml.ZOOM_TYPE_RANGE, 100)).result == 0
    assert s.camera.thermal_digital_zoom_x == 8.0
    assert (await p.ack(CAMERA, ml.MAV_CMD_CAMERA_TRACK_RECTANGLE, 0.3, 0.4, 0.6, 0.5)).result == 0
    assert s.camera.tracking == "tracking"
    loc = s.dialect.decode([f for f in s.received if f.ident == "LOC"][-1]).fields
    # the box as ArduPilot's TOPOTEK driver sends it: centre 0, edges +-1000
    assert (loc["x_px"], loc["y_px"], loc["width_px"], loc["height_px"]) == (-100, -100, 600, 200)
    s.device.scene_height_m = 50.0 if hasattr(s.device, "scene_height_m") else None
    ack = await p.ack(CAMERA, 512, 132)
    assert ack.result in (ml.MAV_RESULT_ACCEPTED, ml.MAV_RESULT_TEMPORARILY_REJECTED)


async def test_fov_status_and_photo_position_with_a_vehicle(rig) -> None:
    p = rig.peer
    autopilot = type(p)(sysid=1, compid=1)
    await autopilot.connect(rig.bridge.addresses[0][1])
    try:
        rig.sim.gimbal.angle("pitch", -45.0)
        await eventually(lambda: abs(rig.sim.gimbal.pitch_deg + 45) < 0.01)
        await eventually(
            lambda: rig.bridge.cam.attitude is not None and abs(rig.bridge.cam.attitude.pitch_deg + 45) < 0.01
        )
        autopilot.send(ml.MAVLink_attitude_message(0, 0.0, 0.0, 0.0, 0, 0, 0))
        autopilot.send(ml.MAVLink_global_position_int_message(0, 470000000, 80000000, 600000, 100000, 0, 0, 0, 0))
        fov = await p.request(CAMERA, 271, "CAMERA_FOV_STATUS")
        assert fov.lat_camera == 470000000 and fov.alt_camera == 600000
        # The field of view is the profile's (1x: the C12 has no optical zoom), the vertical one
        # that of a pinhole of the stream's aspect ratio; the thermal camera gives its own lens's.
        visible, thermal = (rig.sim.device.model.video_stream(lens) for lens in ("visible", "thermal"))
        assert fov.hfov == pytest.approx(visible.hfov_deg) and fov.vfov == pytest.approx(
            _vfov(visible.hfov_deg, 16 / 9)
        )
        tfov = await p.request(THERMAL, 271, "CAMERA_FOV_STATUS")
        assert tfov.hfov == pytest.approx(thermal.hfov_deg) and tfov.vfov == pytest.approx(
            _vfov(thermal.hfov_deg, 5 / 4)
        )
        # 100 m above home, looking 45 deg down to the north: the picture's centre is 100 m north
        assert abs((fov.lat_image - 470000000) / 1e7 * math.pi / 180 * 6371008.8 - 100.0) < 1.0
        assert fov.lon_image == 80000000 and fov.alt_image == 500000
        ack = await p.ack(CAMERA, ml.MAV_CMD_IMAGE_START_CAPTURE, 0, 0, 1, 3)
        assert ack.result == 0
        img = await p.request(CAMERA, 263, "CAMERA_IMAGE_CAPTURED", param2=0)
        assert img.lat == 470000000 and img.relative_alt == 100000
    finally:
        autopilot.close()
