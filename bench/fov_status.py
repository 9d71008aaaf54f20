"""CAMERA_FOV_STATUS (271) on request, with a terrain model: the time from a ground station's
MAV_CMD_REQUEST_MESSAGE to the CAMERA_FOV_STATUS at that station, through the bridge (sim SIP on
loopback, `--terrain` a synthetic 10 m DEM with hills, the vehicle 300-400 m from the ground).
The goal (issue 36): within 50 ms. Figures, no assertions.

    .venv/bin/python bench/fov_status.py [--requests 200]
"""

from __future__ import annotations

import argparse
import asyncio
import math
import statistics
import tempfile
import time  # bench/ may time with perf_counter
from pathlib import Path
from typing import Any

from pymavlink.dialects.v20 import common as ml

from topgimbal.geo.synthetic import write_dem
from topgimbal.mavlink import Bridge, BridgeConfig
from topgimbal.sim import Simulator

LAT0, LON0 = 47.0, 8.0


async def main(n: int) -> None:
    dem = write_dem(Path(tempfile.mkdtemp(prefix="fov-")) / "hills.tif", LAT0, LON0)
    sim = Simulator("SIP")
    await sim.start(udp=[("127.0.0.1", 0)])
    bridge = Bridge(BridgeConfig(url=sim.url, model="SIP", endpoints=["udpin:127.0.0.1:0"], terrain=str(dem)))
    await bridge.start()
    loop = asyncio.get_running_loop()
    gcs, ap = ml.MAVLink(None, srcSystem=255, srcComponent=190), ml.MAVLink(None, srcSystem=1, srcComponent=1)
    parser = ml.MAVLink(None)
    got: asyncio.Queue[tuple[float, Any]] = asyncio.Queue()

    class P(asyncio.DatagramProtocol):
        def datagram_received(self, data: bytes, addr: Any) -> None:
            for m in parser.parse_buffer(data) or []:
                if m.get_type() == "CAMERA_FOV_STATUS":
                    got.put_nowait((time.perf_counter(), m))

    port = bridge.addresses[0][1]  # type: ignore[index]
    tr, _ = await loop.create_datagram_endpoint(P, remote_addr=("127.0.0.1", port))
    tr_ap, _ = await loop.create_datagram_endpoint(asyncio.DatagramProtocol, remote_addr=("127.0.0.1", port))
    tr.sendto(ml.MAVLink_heartbeat_message(6, 8, 0, 0, 4, 3).pack(gcs))
    sim.gimbal.angle("pitch", -30.0)
    while bridge.cam.attitude is None or abs(bridge.cam.attitude.pitch_deg + 30.0) > 0.1:
        await asyncio.sleep(0.05)  # the camera has turned and the bridge has heard it
    lat_ms: list[float] = []
    on_dem = 0
    for i in range(n):
        # the vehicle moves a little each time: every answer is a fresh ray cast
        lat, lon = LAT0 - 0.004 + i * 2e-6, LON0 + 0.003
        tr_ap.sendto(ml.MAVLink_attitude_message(0, 0.0, 0.0, math.radians(35.0), 0, 0, 0).pack(ap))
        tr_ap.sendto(ml.MAVLink_global_position_int_message(
            0, round(lat * 1e7), round(lon * 1e7), 640_000, 340_000, 0, 0, 0, 0).pack(ap))  # fmt: skip
        await asyncio.sleep(0.01)
        t0 = time.perf_counter()
        tr.sendto(ml.MAVLink_command_long_message(1, 100, 512, 0, 271, 0, 0, 0, 0, 0, 0).pack(gcs))
        t1, m = await asyncio.wait_for(got.get(), 2.0)
        lat_ms.append((t1 - t0) * 1000)
        on_dem += m.alt_image != 2**31 - 1
    tr.close()
    tr_ap.close()
    await bridge.close()
    await sim.stop()
    xs = sorted(lat_ms)
    print(f"CAMERA_FOV_STATUS on REQUEST_MESSAGE, --terrain (synthetic 10 m DEM), {n} requests over loopback")
    print(f"  p50 {statistics.median(xs):.2f} ms  p95 {xs[int(0.95 * (n - 1))]:.2f} ms  max {xs[-1]:.2f} ms")
    print(f"  image centre on the terrain in {on_dem}/{n} answers")


if __name__ == "__main__":
    ap_ = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap_.add_argument("--requests", type=int, default=200)
    asyncio.run(main(ap_.parse_args().requests))
