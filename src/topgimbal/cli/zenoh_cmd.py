"""`topgimbal zenoh`: serve N cameras on a Zenoh session (docs/fleet.md)."""

from __future__ import annotations

import argparse
import asyncio
import gc
import logging
import sys
from typing import Any

from ..errors import FieldValueError
from .cot_args import add_cot_tls_arguments, cot_tls
from .mavlink_status import add_status_arguments, serve_with_status
from .runtime import run_server, stop_on_signals, wait_stopped


def camera_arg(text: str) -> object:
    from ..fleet.specs import parse_camera

    try:
        return parse_camera(text)
    except FieldValueError as exc:
        raise argparse.ArgumentTypeError(f"{text!r}: expected {exc.allowed}") from None


def _endpoint(text: str) -> str:
    from ..client.zenoh_session import check_endpoint

    try:
        return check_endpoint(text)
    except FieldValueError as exc:
        raise argparse.ArgumentTypeError(f"{text!r}: expected {exc.allowed}") from None


def _rate(text: str) -> float:
    try:
        v = float(text)
    except ValueError:
        v = float("nan")
    if not 0.5 <= v <= 100:
        raise argparse.ArgumentTypeError(f"{text!r}: expected a rate of 0.5..100 Hz")
    return v


def _calls(text: str) -> int:
    if not text.isdigit() or not 1 <= int(text) <= 64:
        raise argparse.ArgumentTypeError(f"{text!r}: expected 1..64 calls")
    return int(text)


def _batch_ms(text: str) -> float:
    try:
        v = float(text)
    except ValueError:
        v = float("nan")
    if not (v == 0 or 1 <= v <= 1000):
        raise argparse.ArgumentTypeError(f"{text!r}: expected 0 (no batch key) or 1..1000 ms")
    return v


def _workers(text: str) -> int:
    from .zenoh_workers import MAX_WORKERS

    if not text.isdigit() or not 0 <= int(text) <= MAX_WORKERS:
        raise argparse.ArgumentTypeError(f"{text!r}: expected 0..{MAX_WORKERS} worker processes (0: automatic)")
    return int(text)


def _check_mavlink(specs: list[Any], sysid: int, cameras_wanted: bool, thermal: bool) -> str | None:
    from ..mavlink.bridge import BridgeConfigError
    from ..mavlink.multi import allocate

    if not 1 <= sysid <= 255:
        return f"--sysid {sysid}: expected 1..255"
    try:
        allocate([(s.name, s.url, s.model) for s in specs], cameras_wanted=cameras_wanted, thermal=thermal)
    except BridgeConfigError as exc:
        return str(exc)
    return None


async def _start_mavlink(specs: list[Any], args: argparse.Namespace, session: Any) -> Any:
    """The MAVLink bridge of `topgimbal mavlink --camera ...` (same component ids), its only link
    the Zenoh session in BlueOS mavlink-server's key shape (links/zenoh_link.py)."""
    from ..links.zenoh_link import zenoh_link_factory
    from ..mavlink.multi import MultiBridge

    # --cot: each camera its own CoT uid/callsign (its name); the vehicle is the autopilot heard on mavlink/in
    own = [{"cot": args.cot, "cot_name": s.name, "cot_tls": cot_tls(args)} if args.cot else {} for s in specs]
    bridge = MultiBridge([(s.name, s.url, s.model) for s in specs], endpoints=[], sysid=args.sysid,
                         cameras_wanted=not args.no_camera, thermal=not args.no_thermal,
                         link_factories=[zenoh_link_factory(session)], timeout_s=args.timeout,
                         per_camera=own)  # fmt: skip
    await bridge.start()
    return bridge


def register(subparsers: argparse._SubParsersAction[argparse.ArgumentParser]) -> None:
    p = subparsers.add_parser(
        "zenoh",
        help="serve several cameras on a Zenoh session (attitude, state, link, calls; docs/fleet.md)",
        description="Serve N cameras on one Zenoh session: topgimbal/NAME/attitude, /state, /link, a liveliness "
        "token per camera and the queryable topgimbal/NAME/call/METHOD (JSON keyword arguments of the SDK's "
        "methods). Multicast and gossip scouting are off: give --listen and/or --connect endpoints.",
    )
    p.add_argument("--camera", action="append", type=camera_arg, default=[], metavar="NAME=URL,MODEL",
                   help="a camera to serve, e.g. cam1=udp://127.0.0.1:5000,C12 (repeatable)")  # fmt: skip
    p.add_argument("--cameras", metavar="FILE", help="cameras from a file: NAME=URL,MODEL per line, or a JSON list")
    p.add_argument("--listen", action="append", type=_endpoint, default=[], metavar="ENDPOINT",
                   help="Zenoh endpoint to listen on, e.g. tcp/127.0.0.1:7447 (repeatable)")  # fmt: skip
    p.add_argument("--connect", action="append", type=_endpoint, default=[], metavar="ENDPOINT",
                   help="Zenoh endpoint (router or peer) to connect to (repeatable)")  # fmt: skip
    p.add_argument("--mode", choices=("peer", "client"), default="peer", help="Zenoh session mode (default peer)")
    p.add_argument("--config", metavar="FILE", help="Zenoh configuration file (TLS, user/password, access control)")
    p.add_argument("--rate-hz", type=_rate, default=50.0, help="attitude stream rate asked of each camera (default 50)")
    # the default is fleet/batch.py's DEFAULT_BATCH_S (not imported here: `topgimbal --help` stays light)
    p.add_argument("--batch-ms", type=_batch_ms, default=2.0, metavar="MS",
                   help="also put every camera's attitude samples together on topgimbal/@attitude/<server id>, "
                   "one JSON array at most MS ms after its first sample (default 2; 0: no batch key)")  # fmt: skip
    p.add_argument("--max-calls", type=_calls, default=8, help="calls in progress per camera (default 8)")
    p.add_argument("--timeout", type=float, default=1.0, help="camera request timeout, seconds (default 1)")
    p.add_argument("--mavlink-keys", action="store_true",
                   help="also run the MAVLink bridge for the cameras on this session, in BlueOS mavlink-server's keys: "
                   "mavlink/out, mavlink/SYS/COMP/MSG[/FIELD], commands from mavlink/in (at most 6 cameras)")  # fmt: skip
    p.add_argument("--sysid", type=int, default=1, help="MAVLink system id with --mavlink-keys (default 1)")
    p.add_argument(
        "--no-thermal", action="store_true", help="with --mavlink-keys: no MAVLink component for thermal lenses"
    )
    p.add_argument("--no-camera", action="store_true", help="with --mavlink-keys: gimbal components only")
    p.add_argument("--cot", metavar="URL",
                   help="Cursor-on-Target (TAK) of each camera's view and target at 1 Hz, each camera its own uid, "
                   "to udp://HOST:PORT, tcp://HOST:PORT or tls://HOST:PORT (a TAK server); "
                   "the vehicle's position and heading come from the autopilot on mavlink/in (needs --mavlink-keys)")  # fmt: skip
    add_cot_tls_arguments(p)
    p.add_argument("--allow-remote", action="append", default=[], metavar="METHOD",
                   help="make a restricted method remotely callable: set_network, send_raw or request (repeatable; "
                   "off by default: they change the camera's address, persistent settings or send raw frames)")  # fmt: skip
    p.add_argument("--insecure", action="store_true",
                   help="serve on endpoints beyond loopback without Zenoh access control (the log repeats it)")  # fmt: skip
    add_status_arguments(p, json=False, needs="with --mavlink-keys: ")
    p.add_argument("--workers", type=_workers, default=0, metavar="K",
                   help="serve the cameras from K worker processes (default: one per 50,000 samples a second, "
                   "at most 1024 cameras each; docs/fleet.md)")  # fmt: skip
    p.add_argument("--parent-pid", type=int, default=None, help=argparse.SUPPRESS)  # a worker's parent
    p.add_argument("-v", "--verbose", action="store_true", help="log link changes and refused calls")
    p.add_argument("--seconds", type=float, default=None, help=argparse.SUPPRESS)
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    from ..fleet import FleetServer
    from ..fleet.specs import collect, read_camera_file

    specs = list(args.camera) + (read_camera_file(args.cameras) if args.cameras else [])
    if not specs:
        print("topgimbal zenoh: error: give at least one --camera NAME=URL,MODEL or --cameras FILE", file=sys.stderr)
        return 2
    if not args.listen and not args.connect:
        print("topgimbal zenoh: error: give --listen and/or --connect endpoints (scouting is off), "
              "e.g. --listen tcp/127.0.0.1:7447", file=sys.stderr)  # fmt: skip
        return 2
    if not 0.05 <= args.timeout <= 30:
        print(f"topgimbal zenoh: error: --timeout {args.timeout:g}: expected 0.05..30 s", file=sys.stderr)
        return 2
    from ..fleet.specs import MAX_CAMERAS
    from .zenoh_workers import unique, worker_count

    try:
        workers = worker_count(len(specs), args.workers, MAX_CAMERAS, rate_hz=args.rate_hz)
        specs = collect(specs) if workers == 1 else unique(specs)
    except FieldValueError as exc:
        print(f"topgimbal zenoh: error: {exc}", file=sys.stderr)
        return 2
    from ..fleet.access import AccessConfigError, check_allowed, check_exposure

    try:
        allowed = check_allowed(args.allow_remote)
        from ..client.zenoh_session import make_config

        check_exposure([*args.listen, *args.connect], make_config(listen=args.listen, connect=args.connect,
                       mode=args.mode, config_file=args.config), args.insecure, args.mode)  # fmt: skip
    except (AccessConfigError, FieldValueError) as exc:
        print(f"topgimbal zenoh: error: {exc}", file=sys.stderr)
        return 2
    if workers > 1:
        return _run_workers(specs, workers, args, allowed)
    if args.status is not None and not args.mavlink_keys:
        print("topgimbal zenoh: error: --status needs --mavlink-keys (the feeds come from the MAVLink bridge)",
              file=sys.stderr)  # fmt: skip
        return 2
    if args.mavlink_keys:
        problem = _check_mavlink(specs, args.sysid, not args.no_camera, not args.no_thermal)
        if problem:
            print(f"topgimbal zenoh: error: --mavlink-keys: {problem}", file=sys.stderr)
            return 2
    if args.cot:
        from ..outputs.cot import CotConfigError, check_config

        try:
            check_config(args.cot, cot_tls(args), None)
        except CotConfigError as exc:
            print(f"topgimbal zenoh: error: --cot: {exc}", file=sys.stderr)
            return 2
    if args.mavlink_keys:  # as `mavlink --camera`: a camera that answers as another MODEL is not served
        from ..errors import ModelMismatchError
        from .model_guard import check_cameras

        try:
            asyncio.run(check_cameras(specs, args.timeout, auto=False))
        except ModelMismatchError as exc:
            print(f"topgimbal zenoh: error: --mavlink-keys: {exc}", file=sys.stderr)
            return 2
    logging.basicConfig(level=logging.INFO if args.verbose else logging.WARNING, format="%(levelname)s %(message)s")
    if args.cot and (not args.mavlink_keys or args.no_camera):
        # A sighting needs the vehicle's position and heading: only the MAVLink bridge hears them.
        why = "no vehicle source (--mavlink-keys)" if not args.mavlink_keys else "no camera components (--no-camera)"
        for s in specs:
            logging.getLogger("topgimbal.fleet").warning("--cot: %s: %s, sending nothing for this camera", s.name, why)

    async def main() -> None:
        server = FleetServer(specs, listen=args.listen, connect=args.connect, mode=args.mode, config_file=args.config,
                             rate_hz=args.rate_hz, max_calls=args.max_calls,
                             client_options={"timeout_s": args.timeout}, allow_remote=allowed,
                             insecure=args.insecure,
                             batch_s=args.batch_ms / 1000 if args.batch_ms else None)  # fmt: skip
        await server.start()
        bridge = None
        watchers: list[asyncio.Task[None]] = []
        try:
            if args.mavlink_keys:
                bridge = await _start_mavlink(specs, args, server.session)
            where = "; ".join(
                [f"on {', '.join(args.listen)}"] * bool(args.listen) + [f"connected to {', '.join(args.connect)}"] * bool(args.connect)
            )  # fmt: skip
            names = ", ".join(f"{s.name} ({s.model})" for s in specs)
            # What is alive now (every camera's client, the catalog, the modules) lives for the run:
            # keep the collector from walking it again and again. A full collection over 1,000
            # cameras' objects stalled the loop for about 2 s (a 2 s call round trip, 3 % of the
            # samples dropped from the full socket buffer meanwhile).
            gc.freeze()
            print(f"zenoh: serving {len(specs)} cameras {where} ({args.mode}): {names}", flush=True)
            if server.protection.startswith("INSECURE"):
                print(f"zenoh: {server.protection}", file=sys.stderr, flush=True)
            if bridge is not None:
                ids = "; ".join(f"{a.name}: gimbal {a.gimbal_compid}, cameras "
                                f"{','.join(map(str, a.camera_compids)) or 'none'}" for a in bridge.allocations)  # fmt: skip
                print(f"zenoh: MAVLink keys mavlink/{args.sysid}/COMP/MSG, commands from mavlink/in: {ids}", flush=True)
            stop = stop_on_signals()
            if args.parent_pid is not None:  # a worker (zenoh_workers.py): ends with its parent
                from .zenoh_workers import watch_parent

                watchers.append(asyncio.ensure_future(watch_parent(args.parent_pid, stop)))
            named = [] if bridge is None else [
                (f"{a.name} ({a.model})", b) for b, a in zip(bridge.bridges, bridge.allocations, strict=True)
            ]  # fmt: skip
            await serve_with_status(named, args, wait_stopped(stop, args.seconds))
        finally:
            for w in watchers:
                w.cancel()
            if bridge is not None:
                await bridge.close()
            await server.close()

    from ..fleet.server import DuplicateCameraError

    try:
        return run_server(main())
    except DuplicateCameraError as exc:
        print(f"topgimbal zenoh: error: {exc}", file=sys.stderr)
        return 2


def _where(args: argparse.Namespace) -> str:
    return "; ".join(
        [f"on {', '.join(args.listen)}"] * bool(args.listen) + [f"connected to {', '.join(args.connect)}"] * bool(args.connect)
    )  # fmt: skip


def _run_workers(specs: list[Any], workers: int, args: argparse.Namespace, allowed: frozenset[str]) -> int:
    """More cameras than one process serves: zenoh_workers.py (`allowed` is checked; workers re-check)."""
    from .zenoh_workers import refused_with_workers, serve_workers

    problem = refused_with_workers(args)
    if problem:
        print(f"topgimbal zenoh: error: {problem}", file=sys.stderr)
        return 2
    if args.mode == "client" and not args.connect:
        print("topgimbal zenoh: error: --mode client needs --connect", file=sys.stderr)
        return 2
    logging.basicConfig(level=logging.INFO if args.verbose else logging.WARNING, format="%(levelname)s %(message)s")
    try:
        return asyncio.run(serve_workers(specs, workers, args, _where(args)))
    except KeyboardInterrupt:
        return 0
