"""Two cameras behind one bridge, behind MAVProxy used as a router with two ground stations: each
ground station sees both gimbals and cameras through the router, and each drives the camera it
addresses (gimbal 171 -> the second simulator, camera 100 -> the first) with a true COMMAND_ACK."""

from __future__ import annotations

import asyncio
import math
import shutil
import signal
import socket
import sys
from pathlib import Path

import pytest
from pymavlink.dialects.v20 import common as ml

from topgimbal.mavlink.multi import MultiBridge
from topgimbal.sim import Simulator

from .conftest import Peer, eventually

pytestmark = [pytest.mark.external, pytest.mark.integration]
NAN = math.nan


def _free_udp_port() -> int:
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as s:
        s.bind(("127.0.0.1", 0))
        return int(s.getsockname()[1])


def _mavproxy() -> str:
    exe = shutil.which("mavproxy.py", path=str(Path(sys.executable).parent)) or shutil.which("mavproxy.py")
    assert exe, "MAVProxy is part of the dev install (pyproject's dev extra)"
    return exe


async def test_two_ground_stations_through_mavproxy(tmp_path: Path) -> None:
    sims = [Simulator("C12"), Simulator("C12")]
    for s in sims:
        await s.start(udp=[("127.0.0.1", 0)])
    router_in, gcs1, gcs2 = _free_udp_port(), _free_udp_port(), _free_udp_port()
    proxy = await asyncio.create_subprocess_exec(
        sys.executable, _mavproxy(), f"--master=udpin:127.0.0.1:{router_in}",
        f"--out=udpin:127.0.0.1:{gcs1}", f"--out=udpin:127.0.0.1:{gcs2}",
        "--daemon", "--non-interactive", "--default-modules=", f"--state-basedir={tmp_path}",
        stdout=asyncio.subprocess.DEVNULL, stderr=asyncio.subprocess.DEVNULL, cwd=tmp_path,
        preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_DFL),
    )  # fmt: skip
    multi = MultiBridge([("left", sims[0].url, "C12"), ("right", sims[1].url, "C12")],
                        endpoints=[f"udpout:127.0.0.1:{router_in}"], thermal=False, timeout_s=0.5)  # fmt: skip
    peers = [Peer(255, 190), Peer(254, 190)]
    try:
        await multi.start()
        for peer, port in zip(peers, (gcs1, gcs2), strict=True):
            await peer.connect(port)

        def components(p: Peer) -> set[int]:
            return {m.get_srcComponent() for m in p.messages if m.get_type() == "HEARTBEAT" and m.get_srcSystem() == 1}

        loop = asyncio.get_running_loop()
        end = loop.time() + 90
        # The router learns where a station is from what it sends (its --out udpin: ports open once
        # MAVProxy is up, seconds on a loaded machine): heartbeats every second until it forwards.
        while not all(components(p) >= {154, 171, 100, 101} for p in peers):
            assert loop.time() < end, f"components via MAVProxy: {[sorted(components(p)) for p in peers]}"
            for peer in peers:
                peer.send(ml.MAVLink_heartbeat_message(6, 8, 0, 0, 4, 3))
            await asyncio.sleep(1.0)

        ack = await peers[0].ack(171, ml.MAV_CMD_DO_GIMBAL_MANAGER_PITCHYAW, -20, 15, NAN, NAN, 0, 0, 171, timeout=30)
        assert ack.result == ml.MAV_RESULT_ACCEPTED
        await eventually(lambda: abs(sims[1].gimbal.yaw_deg - 15) <= 0.5, 20, "the right camera turned")
        assert sims[0].gimbal.yaw_deg == 0.0

        ack = await peers[1].ack(100, ml.MAV_CMD_IMAGE_START_CAPTURE, 0, 0, 1, 0, timeout=30)
        assert ack.result == ml.MAV_RESULT_ACCEPTED
        assert sims[0].camera.photos_taken == 1 and sims[1].camera.photos_taken == 0
    finally:
        for peer in peers:
            peer.close()
        await multi.close()
        if proxy.returncode is None:
            proxy.send_signal(signal.SIGINT)
            try:
                await asyncio.wait_for(proxy.wait(), 20)
            except asyncio.TimeoutError:
                proxy.kill()
                await proxy.wait()
        for s in sims:
            await s.stop()
