"""Fair share of a served camera's call places (issue 33.4): F flooding Zenoh sessions each keep 8
slow calls (`wait_attitude` that times out after 1 s) on one camera while an operator's remote
client calls `version()` again and again; prints how many of the operator's calls succeeded and
how many were refused `busy`. Figures, no assertions. Runs the server in this process on loopback
(tcp/127.0.0.1, scouting off), so `PYTHONPATH=<other tree>/src` compares trees.

    python bench/fleet_fairness.py --flooders 4 --seconds 10
    python bench/fleet_fairness.py --flooders 1 --invent --seconds 10   # a new session id per call (issue 43.3)
    python bench/fleet_fairness.py --flooders 0 --seconds 10            # the baseline
"""

from __future__ import annotations

import argparse
import asyncio
import json
import os
import secrets
import socket
import threading
from typing import Any

import zenoh

import topgimbal
from topgimbal.client.remote_keys import RemoteCallError
from topgimbal.fleet import CameraSpec, FleetServer
from topgimbal.sim import Simulator


def _port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return int(s.getsockname()[1])


def _flood(port: int, stop: threading.Event, invent: bool) -> None:
    conf = zenoh.Config()
    for k, v in (("mode", "client"), ("connect/endpoints", [f"tcp/127.0.0.1:{port}"]),
                 ("scouting/multicast/enabled", False), ("scouting/gossip/enabled", False)):  # fmt: skip
        conf.insert_json5(k, json.dumps(v))
    s = zenoh.open(conf)
    zid = str(s.zid())
    payload = '{"newer_than": 1e12, "timeout_s": 1.0}'
    while not stop.is_set():
        hs = [s.get("topgimbal/a/call/wait_attitude", payload=payload, timeout=30,
                    attachment=secrets.token_hex(16) if invent else zid) for _ in range(8)]  # fmt: skip
        for h in hs:
            list(h)
    s.close()


async def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--flooders", type=int, default=4)
    ap.add_argument("--seconds", type=float, default=10.0)
    ap.add_argument("--invent", action="store_true", help="the flooders name a new invented session per call")
    a = ap.parse_args()
    sim = Simulator("C12")
    await sim.start(udp=[("127.0.0.1", 0)])
    port = _port()
    ok = busy = other = 0
    async with FleetServer([CameraSpec("a", sim.url, "C12")], listen=[f"tcp/127.0.0.1:{port}"]) as server:
        stop = threading.Event()
        floods = [asyncio.ensure_future(asyncio.to_thread(_flood, port, stop, a.invent)) for _ in range(a.flooders)]
        await asyncio.sleep(2.0)
        async with topgimbal.connect(f"zenoh/a?connect=tcp/127.0.0.1:{port}") as op:
            end = asyncio.get_running_loop().time() + a.seconds
            while asyncio.get_running_loop().time() < end:
                try:
                    await op.version()
                    ok += 1
                except RemoteCallError as exc:
                    busy += exc.kind == "busy"
                    other += exc.kind != "busy"
                    await asyncio.sleep(0.02)
        stop.set()
        await asyncio.gather(*floods)
        refused: Any = server.cameras["a"].refused
    await sim.stop()
    print(f"{a.flooders} flooders x 8 slow calls{' (invented names)' if a.invent else ''}, {a.seconds:g} s: operator version() ok {ok}, busy {busy}, "
          f"other errors {other}; the server refused {refused} calls in all; load {os.getloadavg()[0]:.1f}")  # fmt: skip


if __name__ == "__main__":
    asyncio.run(main())
