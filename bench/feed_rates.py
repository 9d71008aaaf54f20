"""Host feed rates as the camera receives them, next to ArduPilot's drivers.

For each model with feeds: a simulator on loopback UDP, a client fed a fix, the time and the
vehicle attitude (a `feed_from` source at 10 Hz, as the MAVLink bridge does), and after a settling
second the frames per second of each feed the simulator received over --seconds, plus the order of
one period's position frames.

    python bench/feed_rates.py [--seconds 10] [--models SIP,C12,C11]
"""

from __future__ import annotations

import argparse
import asyncio
import collections
import datetime
import time

import topgimbal
from topgimbal.client.api_feed import FeedSample
from topgimbal.client.feeds import Fix
from topgimbal.sim import Simulator

ARDUPILOT = {
    "SIP": "AP_Mount_Topotek: LAT, LON, ALT, AZI every 100 ms (10 Hz); UTC up to 7 times, ~1 Hz after SD answers",
    "C11": "AP_Mount_SkyDroid (pull request): FAI 10 Hz, TIM 1 Hz",
    "C12": "no ArduPilot driver for the C12's position; ours: FAI 10 Hz, LAT/LON/ALT 2 Hz, TIM 1 Hz",
}


async def measure(model: str, seconds: float) -> None:
    sim = Simulator(model)
    await sim.start(udp=[("127.0.0.1", 0)])
    try:
        async with topgimbal.connect(sim.url, model=model, timeout_s=1, check_model=False) as cam:
            fix = Fix(47.3977419, 8.5455938, 488.2, 90.0)
            utc = datetime.datetime.now(datetime.timezone.utc)
            await cam.feed_from(lambda: FeedSample(fix, utc, (1.0, -2.0, 90.0)), 10.0)
            await asyncio.sleep(1.0)
            n0, t0 = len(sim.received), time.monotonic()
            await asyncio.sleep(seconds)
            frames, t1 = list(sim.received[n0:]), time.monotonic()
        counts = collections.Counter(f.ident for f in frames)
        feeds = cam.feeds.feeds()
        rates = "  ".join(f"{i} {counts[i] / (t1 - t0):.2f}/s (profile {feeds[i]:g})" for i in feeds)
        order = [f.ident for f in frames if f.ident in ("LAT", "LON", "ALT", "AZI")][:8]
        print(f"{model:4} {rates}")
        print(f"     one period's position frames in order: {' '.join(order) or '-'}")
        print(f"     ArduPilot: {ARDUPILOT.get(model, '-')}")
    finally:
        await sim.stop()


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0] if __doc__ else None)
    ap.add_argument("--seconds", type=float, default=10.0)
    ap.add_argument("--models", default="SIP,C12,C11")
    args = ap.parse_args()
    for model in args.models.split(","):
        asyncio.run(measure(model.strip(), args.seconds))


if __name__ == "__main__":
    main()
