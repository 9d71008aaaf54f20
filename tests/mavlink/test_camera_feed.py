"""The autopilot's position, attitude and time reach the camera through the bridge, and the next
photo on the simulated card shows them, read back by exiftool and exifread (not by the code that
wrote the tags)."""

from __future__ import annotations

import asyncio
import contextlib
import datetime
import json
import math
import shutil
import subprocess
from pathlib import Path
from typing import Any

import pytest
from pymavlink.dialects.v20 import common as ml

from topgimbal.mavlink.quaternion import from_euler_deg
from topgimbal.video.media import MediaStore
from topgimbal.video.media_http import MediaServer

from .conftest import Peer, eventually

pytestmark = [
    pytest.mark.external,
    pytest.mark.skipif(shutil.which("exiftool") is None, reason="make exiftool-deps installs exiftool"),
]

LAT, LON, ALT_M, HDG = -35.3632621, 149.1652374, 584.07, 253.5
AP_TIME = datetime.datetime(2024, 3, 9, 4, 5, 6, tzinfo=datetime.timezone.utc)  # the autopilot's, not ours


async def autopilot(peer: Peer, *, fix: bool = True, quaternion: bool = True) -> None:
    """What ArduPilot streams: GLOBAL_POSITION_INT, ATTITUDE, AUTOPILOT_STATE_FOR_GIMBAL_DEVICE
    and SYSTEM_TIME, at 10 Hz."""
    loop = asyncio.get_running_loop()
    t0 = loop.time()
    while True:
        dt = loop.time() - t0
        usec = int((AP_TIME.timestamp() + dt) * 1e6)
        lat, lon = (int(LAT * 1e7), int(LON * 1e7)) if fix else (0, 0)
        peer.send(ml.MAVLink_global_position_int_message(int(dt * 1000), lat, lon, int(ALT_M * 1000), 12000, 0, 0, 0,
                                                         int(HDG * 100)))  # fmt: skip
        peer.send(ml.MAVLink_attitude_message(int(dt * 1000), math.radians(3), math.radians(-4), math.radians(HDG - 360),
                                              0, 0, 0))  # fmt: skip
        if quaternion:
            q = from_euler_deg(5.0, -6.0, HDG - 360)
            peer.send(ml.MAVLink_autopilot_state_for_gimbal_device_message(
                0, 0, int(dt * 1e6), list(q), 0, 0, 0, 0, 0, 0, 0, 0, 0))  # fmt: skip
        peer.send(ml.MAVLink_system_time_message(usec, int(dt * 1000)))
        await asyncio.sleep(0.1)


def exiftool(path: Path) -> dict[str, Any]:
    out = subprocess.run(
        ["exiftool", "-j", "-n", "-G", str(path)], capture_output=True, text=True, check=True, timeout=60
    )
    data: dict[str, Any] = json.loads(out.stdout)[0]
    return data


@pytest.mark.parametrize("model", ["SIP", "C12"])
async def test_the_next_photo_carries_the_autopilots_position_attitude_and_time(rig_factory, tmp_path, model):
    server = MediaServer(tmp_path).start()
    rig = await rig_factory(model, media_url=server.url)
    store = MediaStore(rig.sim, tmp_path).start()
    ap = Peer(sysid=1, compid=1)
    await ap.connect(rig.bridge.addresses[0][1])
    task = asyncio.ensure_future(autopilot(ap))
    try:
        pos = rig.sim.device.state.position

        def fed() -> bool:
            t = rig.sim.device.camera_time()
            return pos.lat_deg is not None and pos.alt_m is not None and t is not None and t.year == AP_TIME.year

        await eventually(fed, 15.0, "position and time at the camera")
        await rig.bridge.cam.call(lambda c: c.set_angles(0.0, -30.0))
        g = rig.sim.device.gimbal
        # at rest (a photo of a moving gimbal would show wherever it got to when the shutter opened)
        # (pitch is stabilised: -30 from the horizon, whatever the vehicle's tilt)
        await eventually(lambda: g.pitch_axis.vel == 0.0 and abs(g.earth()[1] + 30.0) < 0.05, 15.0, "gimbal at -30")
        earth_pitch = g.earth()[1]  # -30 plus the vehicle's pitch where the model is fed it (C12 FAI: -6)
        ack = await rig.peer.ack(100, 2000, 0, 0, 1, 0)  # MAV_CMD_IMAGE_START_CAPTURE, one photo
        assert ack.result == ml.MAV_RESULT_ACCEPTED
        await eventually(
            lambda: len(list(tmp_path.iterdir())) >= 2 and not list(tmp_path.glob("*.part")), 30.0, "photo files"
        )
    finally:
        task.cancel()
        with contextlib.suppress(asyncio.CancelledError):
            await task
        ap.close()
        await store.stop()
        server.stop()
    visible = sorted(p for p in tmp_path.iterdir() if "_T" not in p.name and not p.name.startswith("snap_1"))[0]
    tags = exiftool(visible)
    assert abs(tags["Composite:GPSLatitude"] - LAT) < 1e-5 and abs(tags["Composite:GPSLongitude"] - LON) < 1e-5
    assert abs(tags["EXIF:GPSAltitude"] - ALT_M) < 1.0 and tags["EXIF:GPSAltitudeRef"] == 0
    taken = datetime.datetime.strptime(tags["EXIF:DateTimeOriginal"], "%Y:%m:%d %H:%M:%S")
    assert abs((taken - AP_TIME.replace(tzinfo=None)).total_seconds()) < 120  # the autopilot's day, not today
    assert abs(float(tags["XMP:GimbalPitchDegree"]) - earth_pitch) < 1.0
    assert tags["EXIF:Model"] == model and tags["EXIF:FocalLength"] > 0
    assert abs(float(tags["XMP:GimbalYawDegree"]) - (HDG - 360)) < 1.0  # body yaw 0 + the vehicle's heading
    if model == "C12":  # FAI carries the vehicle attitude, from AUTOPILOT_STATE_FOR_GIMBAL_DEVICE's quaternion
        assert (
            abs(float(tags["XMP:FlightPitchDegree"]) + 6.0) < 0.1
            and abs(float(tags["XMP:FlightRollDegree"]) - 5.0) < 0.1
        )
    captured = [m for m in rig.peer.messages if m.get_type() == "CAMERA_IMAGE_CAPTURED" and m.get_srcComponent() == 100]
    if model == "SIP":  # its CAP answer names the file: file_url points at it
        assert captured and captured[-1].file_url == server.url + visible.name
    else:  # the C12's does not: no URL rather than a guess
        assert captured and captured[-1].file_url == ""
    import exifread  # the second reader

    with visible.open("rb") as f:
        ex = exifread.process_file(f, details=False)
    dms = [float(v.num) / float(v.den) for v in ex["GPS GPSLatitude"].values]
    lat = -(dms[0] + dms[1] / 60 + dms[2] / 3600) if str(ex["GPS GPSLatitudeRef"]) == "S" else 0.0
    assert abs(lat - LAT) < 1e-5 and str(ex["EXIF DateTimeOriginal"]) == tags["EXIF:DateTimeOriginal"]


async def test_no_fix_no_position_feed(rig_factory):
    """An autopilot without a fix (GLOBAL_POSITION_INT at 0, 0): the camera gets no position."""
    rig = await rig_factory("SIP")
    ap = Peer(sysid=1, compid=1)
    await ap.connect(rig.bridge.addresses[0][1])
    task = asyncio.ensure_future(autopilot(ap, fix=False))
    try:
        await eventually(
            lambda: (t := rig.sim.device.camera_time()) is not None and t.year == AP_TIME.year, 15.0, "time"
        )
        await asyncio.sleep(0.5)
        assert rig.sim.device.state.position.lat_deg is None
        assert not any(f.ident in ("LAT", "LON", "ALT") for f in rig.sim.received)
        assert rig.bridge.cam.client is not None and "UTC" in rig.bridge.cam.client.feeds.summary()
    finally:
        task.cancel()
        with contextlib.suppress(asyncio.CancelledError):
            await task
        ap.close()


class ScriptedConnection:
    """pymavlink's `recv_match(blocking=False)` over a list of packets an autopilot sent."""

    def __init__(self, packets: list[bytes]) -> None:
        parser = ml.MAVLink(None)
        self.messages = [m for p in packets for m in parser.parse_buffer(p) or []]

    def recv_match(self, blocking: bool = False) -> Any:
        return self.messages.pop(0) if self.messages else None


async def test_the_sdk_feeds_from_a_mavlink_connection_without_the_bridge(tmp_path):
    import topgimbal
    from topgimbal.mavlink.camera_feed import MavlinkSource
    from topgimbal.sim import Simulator

    ap = ml.MAVLink(None, srcSystem=1, srcComponent=1)
    other = ml.MAVLink(None, srcSystem=7, srcComponent=1)  # another vehicle: not ours
    usec = int(AP_TIME.timestamp() * 1e6)
    packets = [
        ml.MAVLink_global_position_int_message(0, 10, 20, 0, 0, 0, 0, 0, 0).pack(other),
        ml.MAVLink_global_position_int_message(
            0, int(LAT * 1e7), int(LON * 1e7), int(ALT_M * 1000), 0, 0, 0, 0, int(HDG * 100)
        ).pack(ap),
        ml.MAVLink_system_time_message(usec, 0).pack(ap),
        b"\xfd\x09garbage",
    ]
    sim = Simulator("SIP")
    await sim.start(udp=[("127.0.0.1", 0)])
    try:
        async with topgimbal.connect(sim.url, model="SIP", timeout_s=1, check_model=False) as cam:
            await cam.feed_from(MavlinkSource(ScriptedConnection(packets)), rate_hz=10)
            pos = sim.device.state.position
            await eventually(lambda: pos.lat_deg is not None and pos.azimuth_deg is not None, 15.0, "position")
            await eventually(lambda: (t := sim.device.camera_time()) is not None and t.year == AP_TIME.year, 15.0)
            assert abs(pos.lat_deg - LAT) < 1e-5 and abs(pos.lon_deg - LON) < 1e-5  # type: ignore[operator]
            assert abs(pos.azimuth_deg - HDG) < 0.2  # type: ignore[operator]
    finally:
        await sim.stop()
