"""`topgimbal zenoh --mavlink-keys --cot udp://HOST:PORT` as its own process with two simulated
cameras: the autopilot's position and heading put on mavlink/in (BlueOS mavlink-server's JSON, by an
independent Zenoh program), every datagram on a loopback UDP socket parsed by takproto (an
independent TAK implementation): each camera its own uid and callsign, its `<sensor>` at its own
gimbal's elevation, `<__video>` with its RTSP URL, its sensor point of interest and footprint.
Without --mavlink-keys (no vehicle source) nothing is sent and the log says so once per camera."""

from __future__ import annotations

import asyncio
import json
import math
import socket
import sys
import xml.etree.ElementTree as ET
from typing import Any

import pytest
import takproto

from topgimbal.geo import geoid

from .conftest import raw_session
from .test_zenoh_server import _serve, _stop

pytestmark = [pytest.mark.loopback, pytest.mark.integration]

LAT, LON, ALT_M, HEADING_DEG = 47.002, 7.998, 650.0, 250.0
# within the C12's pitch range (-45..), low enough that all four corners of the picture land
PITCH_DEG = {"left": -30.0, "right": -42.0}


def _autopilot(kind: str, seq: int) -> str:
    """The autopilot (system 1, component 1) as mavlink-server hands it to Zenoh."""
    if kind == "ATTITUDE":
        msg: dict[str, Any] = {"type": "ATTITUDE", "time_boot_ms": 0, "roll": 0.0, "pitch": 0.0,
                               "yaw": math.radians(HEADING_DEG)}  # fmt: skip
    else:
        msg = {"type": "GLOBAL_POSITION_INT", "time_boot_ms": 0, "lat": round(LAT * 1e7), "lon": round(LON * 1e7),
               "alt": round(ALT_M * 1000), "relative_alt": 350_000, "hdg": 65535}  # fmt: skip
    return json.dumps({"header": {"system_id": 1, "component_id": 1, "sequence": seq % 256}, "message": msg})


def _udp() -> socket.socket:
    sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    sock.bind(("127.0.0.1", 0))
    sock.setblocking(False)
    return sock


def _drain(sock: socket.socket, into: list[bytes]) -> None:
    while True:
        try:
            into.append(sock.recv(65536))
        except BlockingIOError:
            return


def _detail(msg: Any) -> ET.Element:
    return ET.fromstring(f"<detail>{msg.cotEvent.detail.xmlDetail}</detail>")


def _by_uid(parsed: list[Any]) -> dict[str, list[Any]]:
    out: dict[str, list[Any]] = {}
    for m in parsed:
        out.setdefault(m.cotEvent.uid, []).append(m)
    return out


def _complete(parsed: list[Any]) -> bool:
    """Both cameras seen at their own elevation, with their point of interest and footprint."""
    uids = _by_uid(parsed)
    for name, pitch in PITCH_DEG.items():
        vehicles = uids.get(f"topgimbal-1-{name}", [])
        if not vehicles or not uids.get(f"topgimbal-1-{name}.SPI") or not uids.get(f"topgimbal-1-{name}.footprint"):
            return False
        sensor = _detail(vehicles[-1]).find("sensor")
        if sensor is None or abs(float(sensor.get("elevation", "nan")) - pitch) > 0.1:
            return False
    return True


async def test_each_camera_sends_its_own_cot_from_the_autopilot_on_mavlink_in(sims: Any, zport: int) -> None:
    cams = await sims(2)
    for sim, pitch in zip(cams, PITCH_DEG.values(), strict=True):
        sim.gimbal.angle("pitch", pitch)
    sock = _udp()
    url = f"udp://127.0.0.1:{sock.getsockname()[1]}"
    args = ["--listen", f"tcp/127.0.0.1:{zport}", "--mavlink-keys", "--cot", url,
            "--camera", f"left={cams[0].url},C12", "--camera", f"right={cams[1].url},C12"]  # fmt: skip
    proc = await _serve(args)
    session = await asyncio.to_thread(raw_session, zport)
    data: list[bytes] = []
    try:
        loop = asyncio.get_running_loop()
        end, seq = loop.time() + 90, 0
        while loop.time() < end:
            for kind in ("ATTITUDE", "GLOBAL_POSITION_INT"):
                await asyncio.to_thread(session.put, "mavlink/in", _autopilot(kind, seq))
                seq += 1
            await asyncio.sleep(0.5)
            _drain(sock, data)
            parsed = [takproto.parse_proto(bytearray(d)) for d in data]
            if all(m is not None for m in parsed) and _complete(parsed):
                break
    finally:
        await asyncio.to_thread(session.close)
        code = await _stop(proc)
        sock.close()
    assert proc.stderr is not None
    err = (await proc.stderr.read()).decode()
    assert code == 0 and "Traceback" not in err, err
    parsed = [takproto.parse_proto(bytearray(d)) for d in data]
    assert data and all(m is not None for m in parsed)  # every datagram parses
    assert _complete(parsed), sorted(_by_uid(parsed))
    uids = _by_uid(parsed)
    callsigns = set()
    for name in PITCH_DEG:
        vehicle = uids[f"topgimbal-1-{name}"][-1]
        assert vehicle.cotEvent.type == "a-f-A-M-F-Q"
        assert vehicle.cotEvent.lat == pytest.approx(LAT, abs=1e-7) and vehicle.cotEvent.lon == pytest.approx(
            LON, abs=1e-7
        )
        d = _detail(vehicle)
        sensor, video = d.find("sensor"), d.find("__video")
        assert sensor is not None and video is not None
        callsigns.add(vehicle.cotEvent.detail.contact.callsign)  # takproto lifts <contact> out of the XML
        assert float(sensor.get("azimuth", "nan")) == pytest.approx(HEADING_DEG, abs=0.5)
        assert float(sensor.get("fov", "nan")) > 0 and float(sensor.get("range", "0")) > 300
        assert video.get("url", "").startswith("rtsp://127.0.0.1")
        spi = uids[f"topgimbal-1-{name}.SPI"][-1]
        assert spi.cotEvent.type == "b-m-p-s-p-i"
        link = _detail(spi).find("link")
        assert link is not None and link.get("uid") == f"topgimbal-1-{name}"
        # flat ground at home (MSL), as hae: above the ellipsoid by the EGM96 undulation there
        n = geoid.default().undulation_m(spi.cotEvent.lat, spi.cotEvent.lon)  # type: ignore[union-attr]
        assert spi.cotEvent.hae == pytest.approx(ALT_M - 350.0 + n, abs=0.5)
        points = [lk.get("point") for lk in _detail(uids[f"topgimbal-1-{name}.footprint"][-1]).findall("link")]
        assert len(points) == 5 and points[0] == points[-1]
    assert len(callsigns) == 2
    # the steeper camera's point of interest is nearer the vehicle
    near = {n: uids[f"topgimbal-1-{n}.SPI"][-1].cotEvent for n in PITCH_DEG}
    dist = {n: math.hypot(e.lat - LAT, (e.lon - LON) * math.cos(math.radians(LAT))) for n, e in near.items()}
    assert dist["right"] < dist["left"]


async def test_without_a_vehicle_source_nothing_is_sent_and_the_log_says_so_once(sims: Any, zport: int) -> None:
    cams = await sims(2)
    sock = _udp()
    url = f"udp://127.0.0.1:{sock.getsockname()[1]}"
    proc = await asyncio.create_subprocess_exec(
        sys.executable, "-m", "topgimbal.cli.main", "zenoh", "--listen", f"tcp/127.0.0.1:{zport}", "--cot", url,
        "--camera", f"left={cams[0].url},C12", "--camera", f"right={cams[1].url},C12", "--seconds", "3",
        stdout=asyncio.subprocess.PIPE, stderr=asyncio.subprocess.PIPE,
    )  # fmt: skip
    out, err_b = await asyncio.wait_for(proc.communicate(), 90)
    data: list[bytes] = []
    _drain(sock, data)
    sock.close()
    err = err_b.decode()
    assert proc.returncode == 0 and b"serving" in out, err
    for name in ("left", "right"):
        assert err.count(f"--cot: {name}: no vehicle source (--mavlink-keys)") == 1, err
    assert data == []


@pytest.mark.parametrize("bad", ["http://127.0.0.1:8087", "udp://127.0.0.1", "127.0.0.1:6969",
                                 "tls://127.0.0.1:8089 --cot-cert client.pem"])  # fmt: skip
async def test_a_cot_target_that_is_not_udp_tcp_tls_host_port_exits_2(bad: str) -> None:
    """Refused before anything starts: a target that is not udp/tcp/tls://HOST:PORT, a client
    certificate without its key."""
    proc = await asyncio.create_subprocess_exec(
        sys.executable, "-m", "topgimbal.cli.main", "zenoh", "--listen", "tcp/127.0.0.1:1", "--cot", *bad.split(),
        "--camera", "c1=udp://127.0.0.1:5001,C12", stdout=asyncio.subprocess.PIPE, stderr=asyncio.subprocess.PIPE,
    )  # fmt: skip
    out, err = await asyncio.wait_for(proc.communicate(), 60)
    assert proc.returncode == 2 and b"serving" not in out
    assert "topgimbal zenoh: error: --cot" in err.decode()
