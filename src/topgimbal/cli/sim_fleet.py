"""`topgimbal sim --fleet N --udp HOST:PORT`: N simulated cameras of one model in one process, on
UDP ports PORT..PORT+N-1 (port 0: N free ports). For a fleet server's load tests and demos
(docs/fleet.md); one process, one event loop: a thousand cameras fit where a thousand processes
would not.

Each camera is its own Simulator (its own state; seed SEED+i); one URL line per camera, in port
order. Options that name one file or one extra server (--state, --truth, --video, --media, --tcp,
--serial) are refused with --fleet: N cameras cannot share them."""

from __future__ import annotations

import argparse
import asyncio
import gc
import sys
from collections.abc import Callable
from typing import TYPE_CHECKING

from ..sim.shared_timer import SharedTimer

if TYPE_CHECKING:
    from ..sim import Simulator

MAX_FLEET = 4096  # cameras per process: each is a socket on one loop (their wake-ups share one timer)
_SINGLE = ("state", "truth", "tcp", "serial", "video", "media")


class FleetArgsError(ValueError):
    """--fleet with options it cannot take."""


def fleet_count(text: str) -> int:
    if not text.isdigit() or not 1 <= int(text) <= MAX_FLEET:
        raise argparse.ArgumentTypeError(f"{text!r}: expected 1..{MAX_FLEET} cameras")
    return int(text)


def fleet_ports(udp: list[tuple[str, int]] | None, n: int) -> list[tuple[str, int]]:
    """The N (host, port) pairs: one --udp HOST:PORT, ports PORT..PORT+N-1 (0: each a free one)."""
    if not udp or len(udp) != 1:
        raise FleetArgsError("--fleet N takes exactly one --udp HOST:PORT (the first camera's port)")
    host, port = udp[0]
    if port and port + n - 1 > 65535:
        raise FleetArgsError(f"--fleet {n} from port {port} goes beyond 65535")
    return [(host, 0 if port == 0 else port + i) for i in range(n)]


def check_fleet_args(args: argparse.Namespace) -> list[tuple[str, int]]:
    given = [f"--{name}" for name in _SINGLE if getattr(args, name, None)]
    if given:
        raise FleetArgsError(f"--fleet serves N cameras: {', '.join(given)} name one camera's file or server")
    return fleet_ports(args.udp, args.fleet)


async def serve_fleet(make: Callable[[int, SharedTimer], Simulator], where: list[tuple[str, int]]) -> int:
    """Starts `make(i, timer)` on `where[i]` for every i, prints the URLs, serves until a signal.
    The cameras wake on one shared timer (sim/shared_timer.py): one loop timer, not one each."""
    from .runtime import stop_on_signals

    sims: list[Simulator] = []
    stop = stop_on_signals()
    timer = SharedTimer()
    try:
        for i, hostport in enumerate(where):
            sim = make(i, timer)
            await sim.start(udp=[hostport])  # a taken port stops the whole fleet, naming it
            sims.append(sim)
        # N devices' objects live for the run: keep the collector from walking them again and again
        # (a full collection over 1,000 simulators stalled every camera's stream and answers).
        gc.freeze()
        print(f"topgimbal sim: {len(sims)} x {sims[0].model}, seeds {sims[0].seed}..{sims[-1].seed}", file=sys.stderr)
        for sim in sims:
            print(sim.url, flush=True)
        await stop.wait()
    finally:
        await asyncio.gather(*(s.stop() for s in sims), return_exceptions=True)
        timer.close()
    return 0
