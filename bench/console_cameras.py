"""A console with several cameras: what the overview grid costs and how fresh it is.

For each N of --cameras, a console with N simulated cameras (`ConsoleServer(sims=[MODEL] * N)`,
simulators and console in this one process, as `topgimbal console --sim ... --sim ...` runs them)
is started; with --zenoh, the N simulators run in a child process (bench/fleet.py's simulator
fleet), a `topgimbal zenoh` process serves them and the console finds them (`--zenoh`), so the CPU
figure is the console's own; then the page's overview poll, GET /api/cameras, is made at the page's own rate (every
OVERVIEW_INTERVAL_S) for --seconds. Prints: start time, the answer's size and round trip p50/p95,
the share of cameras whose attitude in the answer is under 1 s old, and the process's CPU (the
simulators' streams included) over the window.

    python bench/console_cameras.py [--cameras 4,16,64] [--seconds 10] [--model C12] [--zenoh]
"""

from __future__ import annotations

import argparse
import asyncio
import contextlib
import json
import os
import resource
import socket
import statistics
import sys
import tempfile
import time
from collections.abc import AsyncIterator
from pathlib import Path

import aiohttp

from topgimbal.console import ConsoleServer
from topgimbal.console.routes import OVERVIEW_INTERVAL_S


def _cpu_s() -> float:
    r = resource.getrusage(resource.RUSAGE_SELF)
    return r.ru_utime + r.ru_stime


@contextlib.asynccontextmanager
async def zenoh_fleet(n: int) -> AsyncIterator[str]:
    """N simulated C12s (a child process) served by `topgimbal zenoh`: yields its endpoint."""
    tmp = Path(tempfile.mkdtemp(prefix="console-bench-"))
    urls = tmp / "urls"
    fleet = Path(__file__).with_name("fleet.py")
    sims = await asyncio.create_subprocess_exec(sys.executable, str(fleet), "--sim-fleet", str(n), "--out", str(urls))
    server = None
    try:
        while not (urls.exists() and len(urls.read_text().split()) == n):
            await asyncio.sleep(0.1)
        cams = tmp / "cameras"
        cams.write_text("\n".join(f"cam{i}={u},C12" for i, u in enumerate(urls.read_text().split())))
        with socket.socket() as sock:
            sock.bind(("127.0.0.1", 0))
            port = sock.getsockname()[1]
        server = await asyncio.create_subprocess_exec(
            sys.executable, "-m", "topgimbal.cli.main", "zenoh", "--cameras", str(cams),
            "--listen", f"tcp/127.0.0.1:{port}", stdout=asyncio.subprocess.PIPE,
        )  # fmt: skip
        assert server.stdout is not None
        await asyncio.wait_for(server.stdout.readline(), 120)
        yield f"tcp/127.0.0.1:{port}"
    finally:
        for proc in (server, sims):
            if proc is not None and proc.returncode is None:
                proc.terminate()
                await proc.wait()


async def one(n: int, seconds: float, model: str, zenoh: bool) -> None:
    async with contextlib.AsyncExitStack() as stack:
        if zenoh:
            endpoint = await stack.enter_async_context(zenoh_fleet(n))
            t0 = time.monotonic()
            srv = await stack.enter_async_context(ConsoleServer(zenoh=[endpoint], port=0))
        else:
            t0 = time.monotonic()
            srv = await stack.enter_async_context(ConsoleServer(sims=[model] * n, port=0))
        http = await stack.enter_async_context(aiohttp.ClientSession())
        url = srv.base_url + "api/cameras"
        while True:  # every camera's attitude in the overview
            async with http.get(url) as r:
                body = await r.json()
            cams = body["cameras"]
            if (len(cams) == n and all(c["attitude"] is not None for c in cams)) or time.monotonic() - t0 > 120:
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
        how = "zenoh" if zenoh else "local"
        print(f"{n:4d} cameras ({how}) | all shown in {started_s:5.1f} s | /api/cameras {statistics.mean(sizes) / 1024:6.1f} KiB, "
              f"round trip p50 {statistics.median(rtts):6.1f} ms p95 {q[18]:6.1f} ms ({len(rtts)} polls) | "
              f"attitude < 1 s old: {statistics.mean(fresh) * 100:5.1f} % | CPU {cpu:5.1f} % of a core")  # fmt: skip


async def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--cameras", default="4,16,64", help="comma-separated camera counts")
    ap.add_argument("--seconds", type=float, default=10.0)
    ap.add_argument("--model", default="C12")
    ap.add_argument("--zenoh", action="store_true", help="the cameras behind a `topgimbal zenoh` process")
    args = ap.parse_args()
    print(f"overview poll every {OVERVIEW_INTERVAL_S} s (the page's rate); load average {os.getloadavg()}")
    for n in (int(x) for x in args.cameras.split(",")):
        await one(n, args.seconds, args.model, args.zenoh)


if __name__ == "__main__":
    asyncio.run(main())
