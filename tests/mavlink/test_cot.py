"""`mavlink --cot udp://HOST:PORT`: Cursor-on-Target built with pytak, every datagram parsed back
by takproto (an independent TAK implementation): the vehicle with its `<sensor>` and `<__video>`,
the sensor point of interest at CAMERA_FOV_STATUS's image centre, the footprint's corners."""

from __future__ import annotations

import asyncio
import math
import socket
import xml.etree.ElementTree as ET
from pathlib import Path
from typing import Any

import pytest
import takproto
from pymavlink.dialects.v20 import common as ml

from topgimbal.geo import geoid
from topgimbal.geo.synthetic import write_dem
from topgimbal.outputs.cot import CotConfigError, parse_target

from .conftest import eventually

pytestmark = pytest.mark.loopback

CAMERA = 100
LAT0, LON0 = 47.0, 8.0


@pytest.fixture(scope="module")
def dem(tmp_path_factory: pytest.TempPathFactory) -> Path:
    return write_dem(tmp_path_factory.mktemp("dem") / "hills.tif", LAT0, LON0)


async def _receive(sock: socket.socket, until: int, timeout_s: float = 8.0) -> list[bytes]:
    loop = asyncio.get_running_loop()
    got: list[bytes] = []
    end = loop.time() + timeout_s

    def vehicles() -> int:
        return sum(1 for d in got if ET.fromstring(d).get("type") == "a-f-A-M-F-Q")

    while vehicles() < until and loop.time() < end:
        try:
            got.append(sock.recv(65536))
        except BlockingIOError:
            await asyncio.sleep(0.02)
    return got


def _detail(msg: Any) -> ET.Element:
    return ET.fromstring(f"<detail>{msg.cotEvent.detail.xmlDetail}</detail>")


async def test_cot_events_parse_in_takproto_with_the_right_point(rig_factory, dem: Path) -> None:
    sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    sock.bind(("127.0.0.1", 0))
    sock.setblocking(False)
    url = f"udp://127.0.0.1:{sock.getsockname()[1]}"
    rig = await rig_factory("SIP", terrain=str(dem), cot=url, video_urls=["rtsp://127.0.0.1:8554/main"])
    p, s = rig.peer, rig.sim
    autopilot = type(p)(sysid=1, compid=1)
    await autopilot.connect(rig.bridge.addresses[0][1])
    try:
        s.gimbal.angle("pitch", -35.0)
        cam = rig.bridge.cam
        await eventually(lambda: cam.attitude is not None and abs(cam.attitude.pitch_deg + 35) < 0.01)
        lat, lon, alt = LAT0 + 0.002, LON0 - 0.002, 650.0

        async def feed() -> None:
            while True:
                autopilot.send(ml.MAVLink_attitude_message(0, 0.0, 0.0, math.radians(250.0), 0, 0, 0))
                autopilot.send(ml.MAVLink_global_position_int_message(
                    0, round(lat * 1e7), round(lon * 1e7), round(alt * 1000), 350_000, 0, 0, 0, 0))  # fmt: skip
                await asyncio.sleep(0.5)

        feeder = asyncio.ensure_future(feed())
        try:
            await eventually(lambda: rig.bridge.vehicles.fix() is not None)
            fov = await p.request(CAMERA, 271, "CAMERA_FOV_STATUS")
            data = await _receive(sock, until=3)
        finally:
            feeder.cancel()
        parsed = [takproto.parse_proto(bytearray(d)) for d in data]
        assert data and all(m is not None for m in parsed)  # every datagram parses
        by_type: dict[str, list[Any]] = {}
        for m in parsed:
            by_type.setdefault(m.cotEvent.type, []).append(m)
        assert len(by_type["a-f-A-M-F-Q"]) >= 3
        vehicle = by_type["a-f-A-M-F-Q"][-1]
        assert vehicle.cotEvent.lat == pytest.approx(lat, abs=1e-7) and vehicle.cotEvent.lon == pytest.approx(
            lon, abs=1e-7
        )
        d = _detail(vehicle)
        sensor = d.find("sensor")
        assert sensor is not None
        assert float(sensor.get("azimuth", "nan")) == pytest.approx(250.0 % 360, abs=0.5)
        assert float(sensor.get("elevation", "nan")) == pytest.approx(-35.0, abs=0.1)
        assert float(sensor.get("fov", "nan")) == pytest.approx(fov.hfov, abs=0.01)
        assert float(sensor.get("vfov", "nan")) == pytest.approx(fov.vfov, abs=0.01)
        assert float(sensor.get("range", "0")) > 100
        video = d.find("__video")
        assert video is not None and video.get("url") == "rtsp://127.0.0.1:8554/main"
        spi = by_type["b-m-p-s-p-i"][-1]
        assert spi.cotEvent.lat == pytest.approx(fov.lat_image / 1e7, abs=2e-7)
        assert spi.cotEvent.lon == pytest.approx(fov.lon_image / 1e7, abs=2e-7)
        # hae: above the ellipsoid, the image centre's MSL height plus the EGM96 undulation there
        n = geoid.default().undulation_m(spi.cotEvent.lat, spi.cotEvent.lon)  # type: ignore[union-attr]
        assert 40 < n < 60 and spi.cotEvent.hae == pytest.approx(fov.alt_image / 1000 + n, abs=0.01)
        link = _detail(spi).find("link")
        assert link is not None and link.get("uid") == vehicle.cotEvent.uid
        shape = by_type["u-d-f"][-1]
        points = [lk.get("point") for lk in _detail(shape).findall("link")]
        assert len(points) == 5 and points[0] == points[-1]
    finally:
        autopilot.close()
        sock.close()


def test_cot_target_is_udp_tcp_or_tls_host_port() -> None:
    assert parse_target("udp://239.2.3.1:6969") == ("239.2.3.1", 6969)
    assert parse_target("tcp://127.0.0.1:8087") == ("127.0.0.1", 8087)
    assert parse_target("tls://[::1]:8089") == ("::1", 8089)
    for bad in ("http://127.0.0.1:8087", "udp://127.0.0.1", "127.0.0.1:6969"):
        with pytest.raises(CotConfigError):
            parse_target(bad)


async def test_no_cot_for_a_vehicle_at_0_0_before_its_first_fix(rig_factory) -> None:
    """An autopilot sends GLOBAL_POSITION_INT at 0, 0 until its GPS has a fix: no CoT then (not
    the vehicle off the coast of Africa); the first real fix brings the events."""
    sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    sock.bind(("127.0.0.1", 0))
    sock.setblocking(False)
    rig = await rig_factory("SIP", cot=f"udp://127.0.0.1:{sock.getsockname()[1]}")
    autopilot = type(rig.peer)(sysid=1, compid=1)
    await autopilot.connect(rig.bridge.addresses[0][1])
    where = [0.0, 0.0]

    async def feed() -> None:
        while True:
            autopilot.send(ml.MAVLink_attitude_message(0, 0.0, 0.0, 0.0, 0, 0, 0))
            autopilot.send(ml.MAVLink_global_position_int_message(
                0, round(where[0] * 1e7), round(where[1] * 1e7), 650_000, 100_000, 0, 0, 0, 0))  # fmt: skip
            await asyncio.sleep(0.2)

    feeder = asyncio.ensure_future(feed())
    try:
        await eventually(lambda: rig.bridge.vehicles.fix() is not None and rig.bridge.cam.attitude is not None)
        assert rig.bridge.cot is not None
        await asyncio.sleep(2.5)  # two sends or more at 1 Hz with the 0, 0 fix
        before = await _receive(sock, until=1, timeout_s=0.5)
        assert before == [] and rig.bridge.cot.sent == 0
        where[:] = [LAT0, LON0]
        data = await _receive(sock, until=1)
    finally:
        feeder.cancel()
        autopilot.close()
        sock.close()
    vehicle = [m for m in (takproto.parse_proto(bytearray(d)) for d in data) if m.cotEvent.type == "a-f-A-M-F-Q"]
    assert vehicle and (vehicle[0].cotEvent.lat, vehicle[0].cotEvent.lon) == (LAT0, LON0)


def test_several_cameras_each_send_their_own_cot_from_the_cli() -> None:
    """`topgimbal mavlink --camera left=... --camera right=... --cot URL`: each camera its own uid
    and callsign (its name), every datagram parsed by takproto; the autopilot here is a pymavlink
    socket the bridge's udpout link talks to."""
    import threading

    from pymavlink import mavutil

    from topgimbal.cli.main import main
    from topgimbal.sim import BackgroundSimulator

    cot_sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    cot_sock.bind(("127.0.0.1", 0))
    cot_sock.settimeout(0.2)
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as s:
        s.bind(("127.0.0.1", 0))
        ap_port = s.getsockname()[1]
    autopilot = mavutil.mavlink_connection(f"udpin:127.0.0.1:{ap_port}", source_system=1, source_component=1)
    codes: list[int] = []
    data: list[bytes] = []
    with (
        BackgroundSimulator("C12", seed=41, listen={"udp": [("127.0.0.1", 0)]}) as left,
        BackgroundSimulator("SIP", seed=42, listen={"udp": [("127.0.0.1", 0)]}) as right,
    ):
        for sim in (left, right):  # looking down: the image centre lands
            sim.call(lambda s: s.gimbal.angle("pitch", -30.0))
        argv = ["mavlink", "--mavlink", f"udpout:127.0.0.1:{ap_port}", "--cot", f"udp://127.0.0.1:{cot_sock.getsockname()[1]}",
                "--camera", f"left={left.url},C12", "--camera", f"right={right.url},SIP", "--seconds", "20"]  # fmt: skip
        runner = threading.Thread(target=lambda: codes.append(main(argv)))
        runner.start()
        try:
            while runner.is_alive():
                if autopilot.recv_match(blocking=True, timeout=0.3) is not None:  # the bridge's address known
                    autopilot.mav.attitude_send(0, 0.0, 0.0, math.radians(250.0), 0, 0, 0)
                    autopilot.mav.global_position_int_send(0, round((LAT0 + 0.002) * 1e7), round(LON0 * 1e7),
                                                           650_000, 350_000, 0, 0, 0, 65535)  # fmt: skip
                try:
                    data.append(cot_sock.recv(65536))
                except TimeoutError:
                    pass
                uids = {ET.fromstring(d).get("uid") for d in data}
                if {"topgimbal-1-left", "topgimbal-1-right", "topgimbal-1-left.SPI", "topgimbal-1-right.SPI"} <= uids:
                    break
        finally:
            runner.join(60)
            autopilot.close()
            cot_sock.close()
    assert codes == [0]
    parsed = [takproto.parse_proto(bytearray(d)) for d in data]
    assert data and all(m is not None for m in parsed)  # every datagram parses
    vehicles = {m.cotEvent.uid: m for m in parsed if m.cotEvent.type == "a-f-A-M-F-Q"}
    assert set(vehicles) == {"topgimbal-1-left", "topgimbal-1-right"}
    assert {m.cotEvent.detail.contact.callsign for m in vehicles.values()} == {"left 1", "right 1"}
    spis = {m.cotEvent.uid for m in parsed if m.cotEvent.type == "b-m-p-s-p-i"}
    assert spis == {"topgimbal-1-left.SPI", "topgimbal-1-right.SPI"}
