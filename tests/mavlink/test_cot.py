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

from topgimbal.geo.synthetic import write_dem
from topgimbal.mavlink.cot import CotConfigError, parse_target

from .conftest import eventually

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
        assert spi.cotEvent.hae == pytest.approx(fov.alt_image / 1000, abs=0.01)
        link = _detail(spi).find("link")
        assert link is not None and link.get("uid") == vehicle.cotEvent.uid
        shape = by_type["u-d-f"][-1]
        points = [lk.get("point") for lk in _detail(shape).findall("link")]
        assert len(points) == 5 and points[0] == points[-1]
    finally:
        autopilot.close()
        sock.close()


def test_cot_target_must_be_udp_host_port() -> None:
    assert parse_target("udp://239.2.3.1:6969") == ("239.2.3.1", 6969)
    for bad in ("tcp://127.0.0.1:8087", "udp://127.0.0.1", "127.0.0.1:6969"):
        with pytest.raises(CotConfigError):
            parse_target(bad)
