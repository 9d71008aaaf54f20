"""Links, units and the CLI: endpoint strings, peers that come and go, bounds, pure math."""

from __future__ import annotations

import asyncio
import math
from typing import Any

import pytest
from pymavlink.dialects.v20 import common as ml

from topgimbal.cli.main import main
from topgimbal.geo.aim import Geodetic, ground_point, look_at
from topgimbal.mavlink import BridgeConfig, BridgeConfigError, EndpointError, parse_endpoint
from topgimbal.mavlink.gimbal_device import firmware_code
from topgimbal.mavlink.quaternion import from_euler_deg, to_euler_deg

from .conftest import Peer, eventually

pytestmark = pytest.mark.loopback


def test_endpoint_strings() -> None:
    assert parse_endpoint("udpin:0.0.0.0:14550").kind == "udpin"
    assert parse_endpoint("udp:127.0.0.1:14550").kind == "udpin"
    e = parse_endpoint("udpout:127.0.0.1:14550")
    assert (e.kind, e.host, e.port) == ("udpout", "127.0.0.1", 14550)
    assert parse_endpoint("tcpin:127.0.0.1:0").kind == "tcpin"
    s = parse_endpoint("/dev/ttyUSB0,57600")
    assert (s.kind, s.device, s.baud) == ("serial", "/dev/ttyUSB0", 57600)
    assert parse_endpoint("/dev/ttyACM0").baud == 115200
    for bad in ("", "udpout:127.0.0.1:0", "tcp:host", "udpbcast:1.2.3.4:5", "hello", "/dev/ttyS0,fast"):
        with pytest.raises(EndpointError):
            parse_endpoint(bad)


def test_config_checks() -> None:
    ok = dict(url="udp://127.0.0.1:5000", model="C12", endpoints=["udpin:127.0.0.1:0"])
    BridgeConfig(**ok).check()
    for bad in ({"role": "boss"}, {"compid": 1}, {"sysid": 0}, {"attitude_hz": 500}, {"endpoints": []}):
        with pytest.raises((BridgeConfigError, EndpointError)):
            BridgeConfig(**{**ok, **bad}).check()


@pytest.mark.virtual
def test_quaternion_round_trip() -> None:
    for r, p, y in ((0, 0, 0), (5, -30, 120), (-10, 45, -170), (0, -89, 30)):
        e = to_euler_deg(from_euler_deg(r, p, y))
        assert math.isclose(e.roll_deg, r, abs_tol=1e-6) and math.isclose(e.pitch_deg, p, abs_tol=1e-6)
        assert math.isclose(e.yaw_deg, y, abs_tol=1e-6)
    w, _x, _y, z = from_euler_deg(0, 0, 90)  # yaw right 90 deg: rotation about +z (down)
    assert math.isclose(w, math.sqrt(0.5)) and math.isclose(z, math.sqrt(0.5))


@pytest.mark.virtual
def test_geometry() -> None:
    cam = Geodetic(47.0, 8.0, 600.0)
    yaw, pitch = look_at(cam, 90.0, Geodetic(47.0, 8.01, 500.0))  # due east, vehicle heading east
    assert abs(yaw) < 0.01 and -10 < pitch < -7
    hit = ground_point(cam, 0.0, -45.0, 500.0)
    assert hit is not None and abs((hit.lat_deg - 47.0) * math.pi / 180 * 6371008.8 - 100.0) < 0.5
    assert ground_point(cam, 0.0, 10.0, 500.0) is None


@pytest.mark.virtual
def test_firmware_codes() -> None:
    assert firmware_code("1.2.3") == 1 | 2 << 8 | 3 << 16
    assert firmware_code("123") == 1 | 2 << 8 | 3 << 16
    assert firmware_code("010502") == 1 | 5 << 8 | 2 << 16
    assert firmware_code(None) == 0


async def test_peer_that_goes_away_and_a_new_one(rig) -> None:
    p = rig.peer
    p.close()
    q = Peer()
    await q.connect(rig.bridge.addresses[0][1])
    ack = await q.ack(154, ml.MAV_CMD_DO_GIMBAL_MANAGER_PITCHYAW, -5, 0)
    assert ack.result == ml.MAV_RESULT_ACCEPTED
    q.close()


async def test_peer_limit_is_enforced(rig_factory) -> None:
    r = await rig_factory("C12", max_peers=1)
    other = Peer(sysid=200)
    await other.connect(r.bridge.addresses[0][1])
    await eventually(lambda: r.bridge.node.links[0].refused_peers >= 1, 5, "the second peer refused")
    assert not any(m.get_type() == "HEARTBEAT" for m in other.messages)
    other.close()


async def test_tcpin_and_garbage(rig_factory) -> None:
    r = await rig_factory("C12", endpoints=["udpin:127.0.0.1:0", "tcpin:127.0.0.1:0"])
    host, port = r.bridge.addresses[1]
    for _ in range(2):  # connect, leave, come back
        reader, writer = await asyncio.open_connection(host, port)
        mav = ml.MAVLink(None, srcSystem=250, srcComponent=190)
        writer.write(b"not mavlink at all\n" * 20)  # junk first: the parser skips it
        writer.write(ml.MAVLink_command_long_message(1, 154, 512, 0, 283, 0, 0, 0, 0, 0, 0).pack(mav))
        parser = ml.MAVLink(None)
        got = None

        async def read(parser: Any = parser, reader: Any = reader) -> None:
            nonlocal got
            while got is None:
                for m in parser.parse_buffer(await reader.read(4096)) or []:
                    if m.get_type() == "GIMBAL_DEVICE_INFORMATION":
                        got = m

        await asyncio.wait_for(read(), 5)
        assert got is not None and got.model_name == "C12"
        writer.close()
        await eventually(lambda: r.bridge.node.links[1].peer_count == 0)


async def test_tcp_link_reconnects_to_a_ground_station_that_starts_late(rig_factory) -> None:
    import socket

    s = socket.socket()
    s.bind(("127.0.0.1", 0))
    port = s.getsockname()[1]
    s.close()
    await rig_factory("C12", endpoints=["udpin:127.0.0.1:0", f"tcp:127.0.0.1:{port}"])
    seen = asyncio.get_running_loop().create_future()

    async def gcs(reader: asyncio.StreamReader, writer: asyncio.StreamWriter) -> None:
        parser = ml.MAVLink(None)
        while not seen.done():
            data = await reader.read(4096)
            if not data:
                return
            for m in parser.parse_buffer(data) or []:
                if m.get_type() == "HEARTBEAT" and not seen.done():
                    seen.set_result(m)
        writer.close()

    await asyncio.sleep(1.0)  # the bridge is already retrying
    server = await asyncio.start_server(gcs, "127.0.0.1", port)
    try:
        hb = await asyncio.wait_for(seen, 15)
        assert hb.get_srcSystem() == 1
    finally:
        server.close()


def test_cli_runs_a_bridge(capsys) -> None:
    from topgimbal.sim import BackgroundSimulator

    with BackgroundSimulator("C12", listen={"udp": [("127.0.0.1", 0)]}) as sim:
        rc = main(["mavlink", "--url", sim.url, "--model", "C12", "--mavlink", "udpin:127.0.0.1:0", "--seconds", "1"])
    assert rc == 0
    assert "mavlink bridge: udp://127.0.0.1" in capsys.readouterr().out


def test_cli_errors_are_one_line(capsys) -> None:
    assert (
        main(["mavlink", "--url", "udp://127.0.0.1:9", "--model", "C12", "--mavlink", "nonsense"]) == 2
    )  # input refused before anything was sent (issue 35.4)
    err = capsys.readouterr().err
    assert "not a MAVLink endpoint" in err and err.count("\n") == 1
