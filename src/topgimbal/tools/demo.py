"""`make demo`: a simulated C12 and the web console in one process, on 127.0.0.1.

    python -m topgimbal.tools.demo [--model C12] [--port 8080] [--seconds N]

Uses port 8080, or any free port when 8080 is taken; prints the URL and runs until Ctrl-C (or
for N seconds)."""

from __future__ import annotations

import argparse
import asyncio
import contextlib
import socket
import sys
from collections.abc import Sequence

from ..console import ConsoleServer

HOST = "127.0.0.1"


def port_free(port: int, host: str = HOST) -> bool:
    with socket.socket(socket.AF_INET, socket.SOCK_STREAM) as s:
        try:
            s.bind((host, port))
        except OSError:
            return False
    return True


async def run_demo(model: str, port: int, seconds: float | None, seed: int = 0) -> ConsoleServer:
    chosen = port if port == 0 or port_free(port) else 0
    server = ConsoleServer(sim_model=model, sim_seed=seed, host=HOST, port=chosen)
    await server.start()
    try:
        note = "" if chosen == port else f" (port {port} is taken: using {server.bound_port})"
        print(f"topgimbal demo: simulated {model} at {server.url}{note}", flush=True)
        print(f"console: {server.page_url}", flush=True)
        for lens, url in getattr(getattr(server.video, "sim_video", None), "urls", {}).items():
            print(f"{lens} video: {url}", flush=True)  # topgimbal.video (RTSP; the console shows it)
        print("press Ctrl-C to stop" if seconds is None else f"stopping after {seconds:g} s", flush=True)
        await server.serve_forever(seconds)
    finally:
        await server.stop()
    return server


def main(argv: Sequence[str] | None = None) -> int:
    ap = argparse.ArgumentParser(prog="python -m topgimbal.tools.demo", description=__doc__.splitlines()[0])
    ap.add_argument("--model", default="C12", help="simulated model (default C12)")
    ap.add_argument("--port", type=int, default=8080, help="console port (default 8080; a free one if taken)")
    ap.add_argument("--seconds", type=float, default=None, help="exit after N seconds (default: run until Ctrl-C)")
    ap.add_argument("--seed", type=int, default=0, help="simulator seed")
    args = ap.parse_args(argv)
    with contextlib.suppress(KeyboardInterrupt):
        asyncio.run(run_demo(args.model, args.port, args.seconds, args.seed))
    return 0


if __name__ == "__main__":
    sys.exit(main())
