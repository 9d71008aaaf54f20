"""`get_attitude()` while an attitude stream runs, against the simulator on loopback UDP.

The stream's frames are the attitude query's own answers (E12). Before the fix in client/engine.py
(`Engine.set_stream`) they were counted as copies of the last answer; the link was then taken as
one that copies frames, and each query waited for `dup_window_s` (50 ms) without a frame on its key,
which a 50 Hz stream never leaves: p50 282 ms, max 9.6 s. Prints, for the same calls without and
with a stream consumer running: round trip p50 / p99 / max and the link counters that say why
(`deferred`, `duplicates`). No assertions (tests/client/test_client_streams.py has those).

    python bench/stream_query.py [--calls 50] [--model C12] [--rate-hz 50]

The C12 profile paces commands 40 ms apart: back-to-back calls take that long whatever happens.
"""

from __future__ import annotations

import argparse
import asyncio
import os
import time

import topgimbal
from topgimbal.sim import Simulator


def pct(values: list[float], p: float) -> float:
    s = sorted(values)
    return s[min(len(s) - 1, round(p / 100 * (len(s) - 1)))]


async def calls(cam: topgimbal.AsyncClient, n: int) -> list[float]:
    out = []
    for _ in range(n):
        t = time.perf_counter()
        await cam.get_attitude()
        out.append(time.perf_counter() - t)
    return out


async def run(model: str, n: int, rate_hz: float) -> None:
    sim = Simulator(model)
    await sim.start(udp=[("127.0.0.1", 0)])
    try:
        async with topgimbal.connect(sim.url, model=model) as cam:
            idle = await calls(cam, n)
            samples = 0

            async def consume() -> None:
                nonlocal samples
                async for _att in cam.attitude(rate_hz):
                    samples += 1

            task = asyncio.ensure_future(consume())
            while samples < 10:
                await asyncio.sleep(0.01)
            before = dict(cam.stats.as_dict())
            streaming = await calls(cam, n)
            after = cam.stats.as_dict()
            task.cancel()
            for name, xs in (("no stream", idle), (f"stream at {rate_hz:g} Hz", streaming)):
                ms = [x * 1000 for x in xs]
                print(f"get_attitude, {name:16} p50 {pct(ms, 50):7.1f} ms  p99 {pct(ms, 99):7.1f} ms  "
                      f"max {max(ms):7.1f} ms  ({len(ms)} calls)")  # fmt: skip
            delta = {k: int(after[k] or 0) - int(before[k] or 0) for k in ("deferred", "duplicates", "retries")}
            print(f"during the streaming calls: {delta}, stream samples {samples}")
    finally:
        await sim.stop()


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--calls", type=int, default=50)
    ap.add_argument("--model", default="C12")
    ap.add_argument("--rate-hz", type=float, default=50.0)
    args = ap.parse_args()
    print(f"load average: {' '.join(f'{x:.2f}' for x in os.getloadavg())}")
    asyncio.run(run(args.model, args.calls, args.rate_hz))


if __name__ == "__main__":
    main()
