"""Issue 41.9: `topgimbal console --autopilot HOST:PORT` shows the autopilot's fix and where the
camera looks from it, with nothing typed and nothing fed: GET api/where from an autopilot's
GLOBAL_POSITION_INT on a loopback port (heading 30, 120 m above home), the target on flat ground
at home altitude within 1 m of an independent flat-earth solution. Garbage on the port is
dropped; a bad address is refused with the option's name."""

from __future__ import annotations

import asyncio
import math
import socket

import aiohttp
import pytest
from pymavlink.dialects.v20 import common as ml

from topgimbal.console import ConsoleServer
from topgimbal.console.autopilot import AutopilotAddressError
from topgimbal.console.config import ConsoleConfig, ServeOptions, SimSource
from topgimbal.sim import scene

pytestmark = pytest.mark.loopback

LAT, LON, HOME, HEIGHT, HEADING = -33.9, 151.2, 40.0, 120.0, 30.0


def metres(a: tuple[float, float], b: tuple[float, float]) -> float:
    n = (a[0] - b[0]) * 111_195.0
    e = (a[1] - b[1]) * 111_195.0 * math.cos(math.radians(LAT))
    return math.hypot(n, e)


def position_packet(hdg_cdeg: int) -> bytes:
    mav = ml.MAVLink(None, srcSystem=1, srcComponent=1)
    msg = ml.MAVLink_global_position_int_message(
        1000, round(LAT * 1e7), round(LON * 1e7), round((HOME + HEIGHT) * 1000), round(HEIGHT * 1000), 0, 0, 0,
        hdg_cdeg,
    )  # fmt: skip
    return bytes(msg.pack(mav))


async def test_the_autopilots_fix_and_the_target() -> None:
    config = ConsoleConfig(SimSource("SIP"), ServeOptions(port=0), autopilot="127.0.0.1:0")
    server = ConsoleServer(config=config)
    await server.start()
    try:
        assert server.autopilot is not None and server.sim is not None
        where_url = server.base_url + "api/where"
        sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        async with aiohttp.ClientSession() as http:
            async with http.get(where_url) as r:
                assert (await r.json())["vehicle"] is None
            server.sim.gimbal.angle("yaw", 10.0)
            server.sim.gimbal.angle("pitch", -30.0)
            sock.sendto(b"\xfd not mavlink at all", server.autopilot.address)
            for _ in range(100):
                sock.sendto(position_packet(round(HEADING * 100)), server.autopilot.address)
                await asyncio.sleep(0.1)
                body = await (await http.get(where_url)).json()
                if body["target"] is not None and abs(server.sim.gimbal.pitch_deg + 30) < 0.01:
                    break
            sock.close()
            await asyncio.sleep(0.6)  # past the cache: the answer of the gimbal at rest
            body = await (await http.get(where_url)).json()
        vehicle, target = body["vehicle"], body["target"]
        assert vehicle["source"] == "autopilot" and vehicle["heading_deg"] == pytest.approx(HEADING)
        assert (vehicle["lat_deg"], vehicle["lon_deg"], vehicle["alt_m"]) == pytest.approx((LAT, LON, HOME + HEIGHT))
        # the ray: heading 30 + body yaw 10, 30 degrees down, 120 m above the ground at home altitude
        expected = scene.target_position(LAT, LON, HEADING + 10.0, -30.0, 2 * HEIGHT)
        assert metres((target["lat_deg"], target["lon_deg"]), expected) <= 1.0, (target, expected)
        assert target["alt_m"] == pytest.approx(HOME, abs=0.5) and target["range_m"] == pytest.approx(240.0, abs=1)
        assert server.autopilot.dropped >= 1
    finally:
        await server.stop()


@pytest.mark.parametrize("text", ["14550", "localhost:", "127.0.0.1:99999", ":14550"])
def test_a_bad_autopilot_address_is_refused(text: str) -> None:
    with pytest.raises(AutopilotAddressError, match="--autopilot"):
        ConsoleConfig(SimSource("SIP"), autopilot=text)
