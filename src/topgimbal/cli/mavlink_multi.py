"""`topgimbal mavlink --camera NAME=URL,MODEL ...`: several cameras behind one bridge
(mavlink/multi.py allocates the component ids; docs/fleet.md)."""

from __future__ import annotations

import argparse
import asyncio
import logging
import os
import sys

from .runtime import stop_on_signals, wait_stopped
from .zenoh_cmd import camera_arg


def add_fleet_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("--camera", action="append", type=camera_arg, default=[], metavar="NAME=URL,MODEL",
                   help="several cameras on one bridge (repeatable, instead of --url/--model): gimbals 154, 171.., "
                   "cameras 100.. allocated in order")  # fmt: skip


def run_multi(args: argparse.Namespace) -> int:
    from ..mavlink.bridge import BridgeConfigError
    from ..mavlink.multi import MultiBridge

    if getattr(args, "url", None) and args.url != os.environ.get("TOPGIMBAL_URL"):
        print("topgimbal mavlink: error: give either --url/--model (one camera) or --camera (several)", file=sys.stderr)
        return 2
    cameras = [(c.name, c.url, c.model) for c in args.camera]
    common = dict(role=args.role, attitude_hz=args.attitude_hz, stream_hz=args.stream_hz, range_hz=args.range_hz,
                  timeout_s=args.timeout, silence_s=args.silence,
                  signing_key=getattr(args, "signing_key", None),
                  definition_http=None if args.definition_http == "off" else args.definition_http,
                  definition_host=getattr(args, "definition_host", None),
                  request_streams=not getattr(args, "no_request_streams", False))  # fmt: skip
    try:
        multi = MultiBridge(cameras, endpoints=list(args.mavlink), sysid=args.sysid, cameras_wanted=not args.no_camera,
                            thermal=not args.no_thermal, max_peers=args.max_peers, **common)  # fmt: skip
    except BridgeConfigError as exc:
        print(f"topgimbal mavlink: error: {exc}", file=sys.stderr)
        return 2
    logging.basicConfig(level=logging.INFO if args.verbose else logging.WARNING, format="%(levelname)s %(message)s")

    async def main() -> None:
        await multi.start()
        addrs = ", ".join(f"{link} ({a[0]}:{a[1]})" if a else str(link)
                          for link, a in zip(multi.node.links, multi.addresses, strict=True))  # fmt: skip
        parts = "; ".join(f"{a.name} ({a.model}): gimbal {a.gimbal_compid}, cameras "
                          f"{','.join(map(str, a.camera_compids)) or 'none'}" for a in multi.allocations)  # fmt: skip
        print(f"mavlink bridge: {len(cameras)} cameras <-> {addrs}, system {args.sysid}: {parts}", flush=True)
        stop = stop_on_signals()
        try:
            await wait_stopped(stop, args.seconds)
        finally:
            await multi.close()

    try:
        asyncio.run(main())
    except KeyboardInterrupt:
        print("stopped", file=sys.stderr)
    return 0
