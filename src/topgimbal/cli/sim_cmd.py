"""`topgimbal sim`: run a virtual camera until Ctrl-C / SIGTERM.

    topgimbal sim --model C12                 # the model's documented endpoints on 127.0.0.1
    topgimbal sim --model SIP --udp 127.0.0.1:0 --serial pty --faults drop=0.1 --seed 3

Prints one line per bound endpoint (its URL), then serves; state is flushed on exit. A camera port
that is taken (given or documented) stops it with one line naming the address and suggesting port 0:
clients are configured with a camera's port, so it is never moved silently.
"""

from __future__ import annotations

import argparse
import logging
import sys
from typing import TYPE_CHECKING, Any

from ..protocol import all_models
from ..sim import FaultPlan
from ..sim import quirks as quirk_table
from ..sim.servers import Limits
from ..video import cli as video_cli
from .args import number, writable_output
from .sim_fleet import check_fleet_args, fleet_count, serve_fleet

if TYPE_CHECKING:
    from ..sim import Simulator
    from ..sim.shared_timer import SharedTimer

# A stream faster than this is no camera's (the devices stream at most 100 Hz) and would only
# spin the simulator's loop; nan, 0 or a negative rate stopped the stream without a word.
MAX_STREAM_HZ = 1000.0


def _hostport(text: str) -> tuple[str, int]:
    host, sep, port = text.rpartition(":")
    if not sep or not port.isdigit() or not 0 <= int(port) <= 65535:
        raise argparse.ArgumentTypeError(f"{text!r} is not HOST:PORT (port 0..65535; 0 picks a free port)")
    return host or "127.0.0.1", int(port)


def _faults(text: str) -> FaultPlan:
    try:
        return FaultPlan.parse(text)
    except ValueError as exc:
        raise argparse.ArgumentTypeError(str(exc)) from None


def _quirks(text: str) -> dict[str, bool]:
    try:
        return quirk_table.parse(text)
    except ValueError as exc:
        raise argparse.ArgumentTypeError(str(exc)) from None


def _count(text: str) -> int:
    if not text.isdigit() or int(text) < 1:
        raise argparse.ArgumentTypeError(f"{text!r} is not a count: expected a whole number, 1 or more")
    return int(text)


def _seconds(text: str) -> float:
    try:
        value = float(text)
    except ValueError:
        value = -1.0
    if not 0 <= value < float("inf"):
        raise argparse.ArgumentTypeError(f"{text!r} is not seconds: expected a number >= 0 (0 = no lease)")
    return value


def _model(text: str) -> str:
    for name in all_models():
        if name.lower() == text.lower():
            return name
    raise argparse.ArgumentTypeError(f"{text!r} is not a model; known: {', '.join(all_models())}")


def register(subparsers: argparse._SubParsersAction[argparse.ArgumentParser]) -> None:
    p = subparsers.add_parser(
        "sim",
        help="run a virtual camera (simulator)",
        description="Run a virtual camera on 127.0.0.1 until Ctrl-C. Without --udp/--tcp/--serial it listens "
        "on the model's documented transport and ports (C12: UDP 5000; C10: UDP 5000, TCP 5000, UDP 9002; "
        "C20: TCP 5000; SIP: UDP 9003 and a pty serial line).",
    )
    p.add_argument(
        "--model", dest="sim_model", type=_model, help="device model (default: the global --model, else C12)"
    )
    p.add_argument("--udp", action="append", type=_hostport, metavar="HOST:PORT", help="listen on UDP (repeatable)")
    p.add_argument("--tcp", action="append", type=_hostport, metavar="HOST:PORT", help="listen on TCP (repeatable)")
    p.add_argument("--fleet", type=fleet_count, metavar="N",
                   help="N cameras of the model in this process, on UDP ports PORT..PORT+N-1 of the one --udp "
                   "HOST:PORT (port 0: free ports); one URL line each (docs/fleet.md)")  # fmt: skip
    p.add_argument(
        "--serial",
        action="append",
        metavar="DEVICE",
        help="serve a serial device at 115200 8N1, or 'pty' for a new pseudo-terminal whose path is printed",
    )
    p.add_argument(
        "--state",
        metavar="FILE",
        help="keep persistent settings in FILE (a change is on disk before its reply is sent)",
    )
    p.add_argument(
        "--faults",
        type=_faults,
        metavar="PLAN",
        help=f"fault plan: KEY=VALUE,... (keys: {', '.join(FaultPlan.keys())}) or a .json file",
    )
    p.add_argument(
        "--quirks",
        type=_quirks,
        metavar="LIST",
        help=f"turn quirks on (NAME) or off (-NAME): {', '.join(quirk_table.QUIRKS)}",
    )
    p.add_argument("--seed", type=int, default=0, help="seed for every random choice (default 0)")
    p.add_argument(
        "--terrain",
        metavar="DEM.tif",
        help="ground for the laser (SLR, LRF): a GeoTIFF DEM in lat/lon; the host's LAT/LON/ALT (MSL) "
        "place the camera (default: flat ground, ALT the height above it)",
    )
    p.add_argument(
        "--stream-hz",
        type=number(low=0, low_open=True, high=MAX_STREAM_HZ, what="a stream rate"),
        default=10.0,
        help=f"TOPOTEK GAA/GIA stream rate, above 0 and up to {MAX_STREAM_HZ:g} Hz (default 10)",
    )
    d = Limits()
    p.add_argument(
        "--udp-lease",
        type=_seconds,
        default=d.udp_lease_s,
        metavar="S",
        help=f"forget a UDP host and stop its streams after S seconds without a datagram from it "
        f"(default {d.udp_lease_s:g}; 0 = never)",
    )
    for flag, default, help_text in (
        (
            "--max-udp-peers",
            d.max_udp_peers,
            "UDP hosts remembered per endpoint; the least recently heard is forgotten",
        ),
        ("--max-tcp-clients", d.max_tcp_clients, "TCP connections per endpoint; more are closed at once"),
        (
            "--tcp-buffer-kib",
            d.tcp_buffer_bytes // 1024,
            "KiB unsent to a TCP client before it is dropped as not reading",
        ),
    ):
        p.add_argument(flag, type=_count, default=default, metavar="N", help=f"{help_text} (default {default})")
    p.add_argument("--allow-any-address", action="store_true", help=argparse.SUPPRESS)
    video_cli.add_arguments(p)  # --video, --video-port, ... (topgimbal.video)
    video_cli.add_media_arguments(p)  # --media DIR, --media-port (topgimbal.video.media)
    _add_target_arguments(p)
    p.set_defaults(func=run)


def _add_target_arguments(p: argparse.ArgumentParser) -> None:
    """--target / --truth (docs/tracking.md): targets in the simulated world and the truth file."""
    p.add_argument(
        "--target",
        action="append",
        metavar="SPEC",
        help="a moving target: KEY=VALUE,... (bearing, elevation, speed, heading, span, size, contrast, "
        "temp, hide=START-END+..., name) or a .json file of such objects (repeatable; docs/tracking.md)",
    )
    p.add_argument(
        "--truth", metavar="FILE", help="write the simulator's truth to FILE as JSON lines at 50 Hz (docs/tracking.md)"
    )


def _check_loopback(args: argparse.Namespace) -> None:
    for host, _ in (args.udp or []) + (args.tcp or []):
        if not video_cli.is_loopback(host) and not args.allow_any_address:
            raise ValueError(f"the simulator listens on loopback only (got {host!r}; use 127.0.0.0/8 or ::1)")


def run(args: argparse.Namespace) -> int:
    import asyncio

    from ..sim import Simulator

    _check_loopback(args)
    if getattr(args, "media_port", None) is not None and getattr(args, "media", None) is None:
        raise ValueError("--media-port serves the --media DIR: give --media DIR too")
    if args.state:  # a change is saved before its reply: a state file that cannot be written fails now
        writable_output(args.state, "state file")
    model = args.sim_model or getattr(args, "model", None) or "C12"
    from ..sim.targets import load as load_targets

    targets = load_targets(getattr(args, "target", None) or [])
    if getattr(args, "truth", None):
        writable_output(args.truth, "truth file")
    fleet = check_fleet_args(args) if args.fleet else None

    def make(i: int, timer: SharedTimer | None = None) -> Simulator:
        return Simulator(
            model,
            seed=args.seed + i,
            faults=args.faults,
            state_file=None if fleet else args.state,
            quirks=args.quirks,
            topotek_stream_hz=args.stream_hz,
            terrain=getattr(args, "terrain", None),
            limits=Limits(
                udp_lease_s=args.udp_lease,
                max_udp_peers=args.max_udp_peers,
                max_tcp_clients=args.max_tcp_clients,
                tcp_buffer_bytes=args.tcp_buffer_kib * 1024,
            ),
            targets=targets,
            timer=timer,
        )

    if fleet is not None:
        _log_to_stderr()
        return asyncio.run(serve_fleet(make, fleet))
    sim = make(0)
    listen: dict[str, Any] = {}
    if args.udp or args.tcp or args.serial:
        listen = {"udp": args.udp or [], "tcp": args.tcp or [], "serial": args.serial or []}
    _log_to_stderr()
    return asyncio.run(_serve(sim, listen, args))


def _log_to_stderr() -> None:
    """The servers' limit and state-file lines, one per event, prefixed like the banner."""
    logger = logging.getLogger("topgimbal.sim")
    if not logger.handlers:
        handler = logging.StreamHandler(sys.stderr)
        handler.setFormatter(logging.Formatter("topgimbal sim: %(message)s"))
        logger.addHandler(handler)
        logger.setLevel(logging.INFO)


async def _serve(sim: Simulator, listen: dict[str, Any], args: argparse.Namespace | None = None) -> int:
    from .runtime import stop_on_signals

    await sim.start(**listen)
    stop = stop_on_signals()
    print(f"topgimbal sim: {sim.model} ({sim.dialect.name}), seed {sim.seed}", file=sys.stderr)

    for _kind, url in sim.endpoints:
        print(url, flush=True)
    video = media = truth = None
    try:
        if args is not None and getattr(args, "truth", None):
            from ..sim.truth import TruthWriter

            truth = TruthWriter(sim.device, args.truth)
            await truth.start()
        if args is not None and video_cli.wants_video(args):
            video = await video_cli.start(sim, args)
        if args is not None:
            media = await video_cli.start_media(sim, args)
        await stop.wait()
    finally:
        if media is not None:
            await media.stop()
        if video is not None:
            await video.stop()
        if truth is not None:
            await truth.stop()
        await sim.stop()
    return 0
