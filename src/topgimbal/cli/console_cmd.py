"""`topgimbal console`: the web console for one camera (or an in-process simulator, a watched
proxy, several cameras). The flags become a `console.config.ConsoleConfig` (`build_config`):
one source for the mode the flags name, `ServeOptions`, `LinkOptions`."""

from __future__ import annotations

import argparse
import contextlib
import sys
from typing import TYPE_CHECKING

from ..errors import TopGimbalError
from .args import add_camera_subcommand, add_model_argument

if TYPE_CHECKING:
    from ..console import ConsoleServer
    from ..console.config import ConsoleConfig, FleetSource, Source

DEFAULT_PORT = 8080


def register(subparsers: argparse._SubParsersAction[argparse.ArgumentParser]) -> None:
    p = add_camera_subcommand(
        subparsers,
        "console",
        help="web console: live attitude, pointing, camera, thermal, traffic (aiohttp)",
        description="Serve the web console for a camera (--url and --model) or for a simulator started "
        "in this process (--sim MODEL). Listens on 127.0.0.1 by default; any other --host requires a "
        "token (given with --token, or generated and printed in the URL).",
    )
    add_model_argument(
        p,
        "--sim",
        metavar="MODEL",
        action="append",
        help="run a simulated MODEL in this process on an ephemeral loopback port (repeatable: several cameras, "
        "named sim1, sim2, ...)",
    )
    p.add_argument(
        "--camera",
        action="append",
        type=_camera_arg,
        default=[],
        metavar="NAME=URL,MODEL",
        help="one of several cameras, e.g. left=udp://127.0.0.1:5000,C12 (repeatable; as `topgimbal zenoh`): the "
        "page gets a camera switcher and an overview of every camera",
    )
    p.add_argument("--cameras", metavar="FILE", help="cameras from a file: NAME=URL,MODEL per line, or a JSON list")
    p.add_argument(
        "--zenoh",
        action="append",
        default=[],
        metavar="ENDPOINT",
        help="show the cameras a `topgimbal zenoh` server serves, found by their liveliness tokens, e.g. "
        "tcp/127.0.0.1:7447 (repeatable; scouting stays off)",
    )
    p.add_argument(
        "--zenoh-config",
        metavar="FILE",
        help="Zenoh configuration file for the --zenoh session: the credentials of a server with access control "
        '(e.g. { transport: { auth: { usrpwd: { user: "operator", password: "..." } } } }) or TLS',
    )
    p.add_argument("--seed", type=int, default=0, help="simulator seed (with --sim)")
    p.add_argument("--autopilot", metavar="HOST:PORT",
                   help="listen there for the autopilot's MAVLink (GLOBAL_POSITION_INT): the page shows the vehicle's "
                   "fix and where the camera looks from it (read only: nothing is sent)")  # fmt: skip
    p.add_argument(
        "--faults",
        metavar="PLAN",
        type=_fault_plan,
        help="simulate a bad link (with --sim), as `topgimbal sim --faults`: e.g. silence=20-30 for a camera "
        "that goes quiet from 20 s to 30 s after the start (the page shows LOST)",
    )
    p.add_argument(
        "--proxy",
        action="store_true",
        help="watch a proxy instead of talking to a camera: forward --listen <-> --to in this process and show "
        "the decoded traffic (read-only: the page sends nothing to the camera); needs --model",
    )
    p.add_argument(
        "--listen", metavar="URL", help="with --proxy: where the ground station connects, e.g. udp://127.0.0.1:5600"
    )
    p.add_argument("--to", metavar="URL", help="with --proxy: the camera, e.g. udp://192.168.144.25:5000")
    p.add_argument("--host", default="127.0.0.1", help="address to listen on (default 127.0.0.1)")
    p.add_argument(
        "--port",
        type=_port_arg,
        default=None,
        help=f"port to listen on (default {DEFAULT_PORT}, and a free one printed when that is taken, as `make demo` "
        "does; 0 = any free port); a --port given that is taken is an error",
    )
    p.add_argument("--token", help="access token; required (else generated) when --host is not a loopback address")
    p.add_argument(
        "--allow-host",
        metavar="NAME",
        action="append",
        default=[],
        help="also answer requests for this host name or address (repeatable; loopback names and "
        "the --host address are always allowed, any other Host is refused as DNS rebinding)",
    )
    p.add_argument(
        "--video-url",
        metavar="[LENS=]URL",
        action="append",
        default=[],
        help="where the camera's video is, when not at the model's documented RTSP URL (repeatable, one per "
        "lens: e.g. --video-url visible=rtsp://10.0.0.5:8554/main --video-url thermal=rtsp://...; a URL without "
        "LENS= goes to the model's lenses in order: visible, then thermal)",
    )
    p.add_argument(
        "--video-port",
        metavar="PORT",
        type=int,
        help="the camera's RTSP port, when not the documented one (a port forward): the documented paths on it",
    )
    p.add_argument("--attitude-hz", type=float, default=50.0, help="attitude push rate to the page, at most 50")
    p.add_argument(
        "--seconds", type=float, default=None, help="stop after this many seconds (default: run until Ctrl-C)"
    )
    p.set_defaults(func=run)


def _camera_arg(text: str) -> object:
    from .zenoh_cmd import camera_arg

    return camera_arg(text)


def _several(args: argparse.Namespace) -> bool:
    """Several cameras (the switcher and the overview): --camera, --cameras, --zenoh or --sim twice."""
    sims = args.sim if isinstance(args.sim, list) else []
    return bool(args.camera or args.cameras or args.zenoh or len(sims) > 1)


def _fleet_source(args: argparse.Namespace) -> FleetSource:
    """The cameras of a console of several cameras (ValueError, a usage error, on bad input)."""
    from ..console.config import FleetSource
    from ..fleet.specs import read_camera_file

    specs = list(args.camera) + (read_camera_file(args.cameras) if args.cameras else [])
    single = {"--url": getattr(args, "url", None), "--proxy": args.proxy or args.listen or args.to,
              "--faults": args.faults, "--video-url": args.video_url, "--video-port": args.video_port}  # fmt: skip
    given = [k for k, v in single.items() if v]
    if given:
        raise ValueError(
            f"{', '.join(given)} cannot be combined with --camera, --cameras, several --sim or --zenoh: give every "
            "camera with --camera NAME=URL,MODEL, --sim MODEL or --zenoh ENDPOINT"
        )
    return FleetSource(
        cameras=tuple((c.name, c.url, c.model) for c in specs),
        sims=tuple(args.sim or ()),
        zenoh=tuple(args.zenoh),
        seed=args.seed,
        zenoh_config=args.zenoh_config,
    )


def _port_arg(text: str) -> int:
    """A listening port, 0..65535 (0: any free one): checked here, before the port is probed."""
    from ..console.config import ServeOptions

    try:
        return ServeOptions(port=int(text)).port
    except ValueError:  # not a number, or out of range (ConsoleConfigError)
        raise argparse.ArgumentTypeError(f"{text!r}: give a port from 0 to 65535 (0: any free port)") from None


def _fault_plan(text: str) -> object:
    from ..sim import FaultPlan, FaultPlanError

    try:
        return FaultPlan.parse(text)
    except FaultPlanError as exc:
        raise argparse.ArgumentTypeError(str(exc)) from None


def choose_port(host: str, port: int) -> tuple[int, int | None]:
    """The port to bind, and the port asked for when that one is taken. The console's rule, the same
    as `make demo`'s: a page's port is read off the printed URL, so a taken one falls back to a
    free one. (A camera's port is never moved: `topgimbal sim` stops with an error instead.)"""
    from ..tools.demo import port_free

    if port == 0 or port_free(port, host):
        return port, None
    return 0, port


def build_config(args: argparse.Namespace) -> ConsoleConfig:
    """The ConsoleConfig the arguments describe (raises ValueError on a bad combination)."""
    from ..console.config import ConsoleConfig, LinkOptions, ServeOptions

    source = _source(args)  # first: which camera, then how the page is served
    serve = ServeOptions(
        host=args.host,
        port=DEFAULT_PORT if args.port is None else args.port,
        token=args.token,
        allow_hosts=tuple(args.allow_host),
    )
    return ConsoleConfig(source, serve, LinkOptions(attitude_hz=args.attitude_hz), autopilot=args.autopilot)


def _source(args: argparse.Namespace) -> Source:
    """What the page shows, from the flags: one mode, the mixtures refused in the CLI's words."""
    from ..console import config as cfg

    url = getattr(args, "url", None)
    model = getattr(args, "model", None)
    if _several(args):
        return _fleet_source(args)
    if isinstance(args.sim, list):  # one --sim: the single-camera console, as before
        args.sim = args.sim[0] if args.sim else None
    if args.proxy or args.listen or args.to:
        if not args.proxy:
            raise ValueError("--listen and --to go with --proxy")
        if args.sim is not None:
            raise ValueError("--proxy watches the camera behind it: give --listen and --to, not --sim")
        return cfg.ProxySource(listen=args.listen or "", to=args.to or "", model=model or "")
    if args.video_url or args.video_port is not None:
        _video_options(args, model)
    if args.sim is None and url and not model:
        raise ValueError("give --model with --url (it picks the dialect), e.g. --model SIP")
    if args.sim is not None and url:
        raise ValueError("--sim runs its own simulator: give either --url or --sim")
    if args.sim is not None:
        return cfg.SimSource(model=args.sim, seed=args.seed, faults=args.faults)
    if not url:
        raise cfg.ConsoleConfigError(cfg.NO_SOURCE)
    if args.faults is not None:
        raise cfg.ConsoleConfigError(cfg.FAULTS_NEED_SIM)
    assert model  # refused above without it
    return cfg.CameraSource(
        url=url, model=model, video_urls=video_urls(model, args.video_url), video_port=args.video_port
    )


def build_server(args: argparse.Namespace) -> ConsoleServer:
    """The ConsoleServer the arguments describe (raises ValueError on a bad combination)."""
    from ..console import ConsoleServer

    return ConsoleServer.from_config(build_config(args))


class VideoOptionError(ValueError):
    """A bad --video-url / --video-port: a usage error (exit status 2)."""


def _video_options(args: argparse.Namespace, model: str | None) -> None:
    from ..console.config import check_video_options

    if args.sim is not None or args.proxy:
        raise VideoOptionError(
            "--video-url and --video-port are for a camera given with --url: the simulator of --sim serves its own "
            "video and a watched proxy has no video panel"
        )
    try:
        check_video_options(model, video_urls(model, args.video_url), args.video_port)
    except ValueError as exc:
        raise VideoOptionError(str(exc)) from None


def video_urls(model: str | None, given: list[str]) -> dict[str, str]:
    """`--video-url` values as {lens: URL}: `LENS=URL`, or a bare URL for the next lens of the model
    in order (visible, then thermal). Raises ValueError naming the lenses the model has."""
    from ..video.lens import streams_for

    lenses = [s.lens for s in streams_for(model or "C12")] if given else []
    out: dict[str, str] = {}
    for text in given:
        lens, sep, url = text.partition("=")
        if not sep or "://" in lens:  # a bare URL (its query may hold '=')
            lens, url = next((n for n in lenses if n not in out), ""), text
            if not lens:
                raise ValueError(
                    f"--video-url {text}: the {model} has {len(lenses)} lens(es) ({', '.join(lenses)}), all given"
                )
        if lens in out:
            raise ValueError(f"--video-url: the {lens} lens is given twice")
        out[lens] = url
    return out


async def _serve(server: ConsoleServer, seconds: float | None, taken: int | None = None) -> None:
    from .runtime import stop_on_signals, wait_stopped

    # Before start: SIGTERM (a service manager, `kill`) and Ctrl-C end the console the same orderly
    # way, even when it was started with SIGINT ignored (a background job of a script).
    stop = stop_on_signals()
    await server.start()
    try:
        if taken is not None:
            print(f"topgimbal console: port {taken} is taken: using {server.bound_port}", flush=True)
        print(server.banner(), flush=True)
        await wait_stopped(stop, seconds)
    finally:
        await server.stop()


def run(args: argparse.Namespace) -> int:
    import asyncio

    try:
        import aiohttp  # noqa: F401
    except ImportError:
        print("topgimbal: error: the console needs aiohttp: pip install 'topgimbal[console]'", file=sys.stderr)
        return 1
    try:
        if args.video_url or args.video_port is not None:
            _video_options(args, getattr(args, "model", None))
    except VideoOptionError as exc:
        print(f"topgimbal: error: {exc}", file=sys.stderr)
        return 2
    if args.port is None:  # the default port: a free one when it is taken (the page's URL is printed)
        args.port, taken = choose_port(args.host, DEFAULT_PORT)
    else:  # a port the user chose is meant: never another one (issue 35.6)
        _port, taken = choose_port(args.host, args.port)
        if taken is not None:
            print(f"topgimbal console: error: --port {taken} is taken (another program listens there); "
                  "choose another, or --port 0 for any free one", file=sys.stderr)  # fmt: skip
            return 2
    if args.zenoh_config is not None and not args.zenoh:
        print(f"topgimbal console: error: --zenoh-config {args.zenoh_config}: only with --zenoh ENDPOINT "
              "(the session it configures)", file=sys.stderr)  # fmt: skip
        return 2
    if _several(args):
        try:
            server = build_server(args)
        except (ValueError, TopGimbalError) as exc:  # names, the bound, a camera file, a mix of forms
            print(f"topgimbal console: error: {exc}", file=sys.stderr)
            return 2
    else:
        server = build_server(args)
    with contextlib.suppress(KeyboardInterrupt):
        asyncio.run(_serve(server, args.seconds, taken))
    return 0
