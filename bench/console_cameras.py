"""A console with several cameras: what the overview grid costs and how fresh it is.

For each N of --cameras, a console with N simulated cameras (`ConsoleServer(sims=[MODEL] * N)`,
simulators and console in this one process, as `topgimbal console --sim ... --sim ...` runs them)
is started; then the page's overview poll, GET /api/cameras, is made at the page's own rate (every
OVERVIEW_INTERVAL_S) for --seconds. Prints: start time, the answer's size and round trip p50/p95,
the share of cameras whose attitude in the answer is under 1 s old, and the process's CPU (the
simulators' streams included) over the window.

    python bench/console_cameras.py [--cameras 4,16,64] [--seconds 10] [--model C12]
"""

from __future__ import annotations

import argparse
import asyncio
import json
import os
import resource
import statistics
import time

import aiohttp

from topgimbal.console import ConsoleServer
from topgimbal.console.routes import OVERVIEW_INTERVAL_S


def _cpu_s() -> float:
    r = resource.getrusage(resource.RUSAGE_SELF)
    return r.ru_utime + r.ru_stime


async def one(n: int, seconds: float, model: str) -> None:
    t0 = time.monotonic()
    async with ConsoleServer(sims=[model] * n, port=0) as srv, aiohttp.ClientSession() as http:
        url = srv.base_url + "api/cameras"
        while True:  # every camera's attitude in the overview
            async with http.get(url) as r:
                body = await r.json()
            if all(c["attitude"] is not None for c in body["cameras"]) or time.monotonic() - t0 > 120:
                break
            await asyncio.sleep(0.2)
        started_s = time.monotonic() - t0
        rtts, sizes, fresh = [], [], []
        cpu0, wall0 = _cpu_s(), time.monotonic()
        while time.monotonic() - wall0 < seconds:
            t = time.monotonic()
            async with http.get(url) as r:
                raw = await r.read()
            rtts.append((time.monotonic() - t) * 1000)
            sizes.append(len(raw))
            body = json.loads(raw)
            now = body["now"]
            fresh.append(sum(1 for c in body["cameras"] if c["attitude"] and now - c["attitude"]["t"] < 1.0) / n)
            await asyncio.sleep(max(0.0, OVERVIEW_INTERVAL_S - (time.monotonic() - t)))
        cpu = (_cpu_s() - cpu0) / (time.monotonic() - wall0) * 100
        q = statistics.quantiles(rtts, n=20)
        print(f"{n:4d} cameras | started in {started_s:5.1f} s | /api/cameras {statistics.mean(sizes) / 1024:6.1f} KiB, "
              f"round trip p50 {statistics.median(rtts):6.1f} ms p95 {q[18]:6.1f} ms ({len(rtts)} polls) | "
              f"attitude < 1 s old: {statistics.mean(fresh) * 100:5.1f} % | CPU {cpu:5.1f} % of a core")  # fmt: skip


async def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--cameras", default="4,16,64", help="comma-separated camera counts")
    ap.add_argument("--seconds", type=float, default=10.0)
    ap.add_argument("--model", default="C12")
    args = ap.parse_args()
    print(f"overview poll every {OVERVIEW_INTERVAL_S} s (the page's rate); load average {os.getloadavg()}")
    for n in (int(x) for x in args.cameras.split(",")):
        await one(n, args.seconds, args.model)


if __name__ == "__main__":
    asyncio.run(main())
