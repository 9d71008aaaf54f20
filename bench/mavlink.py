"""MAVLink bridge latency: camera attitude frame -> GIMBAL_DEVICE_ATTITUDE_STATUS at a pymavlink
peer, and a command's round trip through the bridge (MAV_CMD_DO_GIMBAL_MANAGER_PITCHYAW -> final
COMMAND_ACK) next to the same request made directly with the client. Loopback only; figures, no
assertions."""

from __future__ import annotations

import asyncio
import os
import statistics
import time

from pymavlink.dialects.v20 import common as ml

from topgimbal import connect
from topgimbal.mavlink import Bridge, BridgeConfig
from topgimbal.sim import Simulator

N = 200


def pct(xs: list[float], p: float) -> float:
    xs = sorted(xs)
    return xs[min(len(xs) - 1, int(p / 100 * len(xs)))]


async def main() -> None:
    sim = Simulator("C12")
    await sim.start(udp=[("127.0.0.1", 0)])
    bridge = Bridge(
        BridgeConfig(url=sim.url, model="C12", endpoints=["udpin:127.0.0.1:0"], attitude_hz=100, stream_hz=100)
    )
    await bridge.start()
    loop = asyncio.get_running_loop()
    mav = ml.MAVLink(None, srcSystem=255, srcComponent=190)
    parser = ml.MAVLink(None)
    frame_t: list[float] = []
    att_lat: list[float] = []
    acks: asyncio.Queue[float] = asyncio.Queue()

    # camera frame arrival at the bridge's client (the earliest the bridge can know)
    # (first in the listener list, ahead of the gimbal device's: a bench may reach inside)
    bridge.cam._attitude_cbs.insert(0, lambda s: frame_t.append(time.perf_counter()))

    class P(asyncio.DatagramProtocol):
        def datagram_received(self, data: bytes, addr: object) -> None:
            now = time.perf_counter()
            for m in parser.parse_buffer(data) or []:
                if m.get_type() == "GIMBAL_DEVICE_ATTITUDE_STATUS" and frame_t:
                    att_lat.append(now - frame_t[-1])
                elif m.get_type() == "COMMAND_ACK" and m.result != 5:
                    acks.put_nowait(now)

    t, _ = await loop.create_datagram_endpoint(P, remote_addr=("127.0.0.1", bridge.addresses[0][1]))
    t.sendto(ml.MAVLink_heartbeat_message(6, 8, 0, 0, 4, 3).pack(mav))
    await asyncio.sleep(3.0)
    rtt_bridge = []
    for i in range(N):
        t0 = time.perf_counter()
        t.sendto(
            ml.MAVLink_command_long_message(1, 154, 1000, 0, -10 - i % 20, 0, float("nan"), float("nan"), 0, 0, 0).pack(
                mav
            )
        )
        t1 = await asyncio.wait_for(acks.get(), 5)
        rtt_bridge.append(t1 - t0)
    rtt_direct = []
    async with connect(sim.url, model="C12") as cam:
        for i in range(N):
            t0 = time.perf_counter()
            await cam.set_angles(0, -10 - i % 20)
            rtt_direct.append(time.perf_counter() - t0)
    t.close()
    await bridge.close()
    await sim.stop()
    ms = 1000.0
    print(
        f"attitude frame -> GIMBAL_DEVICE_ATTITUDE_STATUS: n={len(att_lat)} p50 {pct(att_lat, 50) * ms:.2f} ms  p99 {pct(att_lat, 99) * ms:.2f} ms"
    )
    print(
        f"PITCHYAW -> COMMAND_ACK through the bridge:    n={N} p50 {pct(rtt_bridge, 50) * ms:.2f} ms  p99 {pct(rtt_bridge, 99) * ms:.2f} ms"
    )
    print(
        f"client.set_angles direct:                     n={N} p50 {pct(rtt_direct, 50) * ms:.2f} ms  p99 {pct(rtt_direct, 99) * ms:.2f} ms"
    )
    print(f"mean bridge overhead: {(statistics.mean(rtt_bridge) - statistics.mean(rtt_direct)) * ms:.2f} ms")
    print("load average (1/5/15 min): " + " / ".join(f"{x:.2f}" for x in os.getloadavg()))


if __name__ == "__main__":
    asyncio.run(main())
