"""`topgimbal mavlink`: present a camera as MAVLink gimbal and camera components."""

from __future__ import annotations

import argparse
import logging

from ..mavlink.features import FEATURES
from ..video.cli import add_video_port_argument
from .args import add_camera_subcommand
from .config_args import config_kwargs, with_flags
from .mavlink_multi import add_fleet_arguments, run_multi
from .mavlink_status import add_status_arguments, bound_links, links_text, serve_with_status
from .model_guard import refuse_wrong_model

GIMBAL_COMPIDS = (154, 171, 172, 173, 174, 175)
CAMERA_COMPIDS = (100, 101, 102, 103, 104)


def register(subparsers: argparse._SubParsersAction[argparse.ArgumentParser]) -> None:
    p = add_camera_subcommand(
        subparsers,
        "mavlink",
        model_help="device model (picks the dialect, limits and capabilities); auto: ask the camera at start",
        auto=True,
        help="MAVLink bridge: the camera as a gimbal (protocol v2) and camera for QGC, MAVSDK, PX4, ArduPilot",
        description="Bridge a camera to MAVLink (pymavlink, MAVLink 2, common dialect). Endpoints use "
        "pymavlink's connection strings: udpin:HOST:PORT, udpout:HOST:PORT, tcp:HOST:PORT, tcpin:HOST:PORT, "
        "or a serial DEVICE[,BAUD]; give --mavlink several times for several links. See docs/mavlink.md.",
    )
    p.add_argument("--mavlink", action="append", required=True, metavar="ENDPOINT", help="MAVLink link (repeatable)")
    add_fleet_arguments(p)
    p.add_argument("--sysid", type=int, default=1, help="MAVLink system id (default 1: the vehicle's)")
    p.add_argument("--compid", type=int, default=None, choices=GIMBAL_COMPIDS, help="gimbal component id (default 154)")
    p.add_argument(
        "--camera-compid",
        type=int,
        default=None,
        choices=CAMERA_COMPIDS,
        help="camera component id (default 100; the thermal lens takes the next one)",
    )
    p.add_argument("--no-camera", action="store_true", help="no camera components, the gimbal only")
    p.add_argument("--no-thermal", action="store_true", help="no second camera component for a thermal lens")
    p.add_argument(
        "--role",
        choices=("device", "manager", "both"),
        default="both",
        help="gimbal role: device (an autopilot manages it: ArduPilot MNT1_TYPE=6, PX4), manager (a non-MAVLink "
        "gimbal behind its own manager), both (default: ground stations drive it directly)",
    )
    p.add_argument("--attitude-hz", type=float, default=20.0, help="GIMBAL_DEVICE_ATTITUDE_STATUS rate (default 20)")
    p.add_argument("--stream-hz", type=float, default=50.0, help="attitude stream asked of the camera (default 50)")
    p.add_argument("--range-hz", type=float, default=1.0, help="rangefinder polling for DISTANCE_SENSOR (0: off)")
    p.add_argument("--video-url", action="append", help="RTSP URL to announce (repeatable; default: the model's)")
    add_video_port_argument(p, "the camera's first RTSP port when not the model's (as sim --video-port)")
    p.add_argument("--video-out", action="append", metavar="[LENS=]udp://HOST:PORT",
                   help="push the lens's stream (default visible) as RTP over UDP to a ground station "
                   "(QGroundControl: port 5600), advertised in VIDEO_STREAM_INFORMATION; repeatable")  # fmt: skip

    p.add_argument("--companion-tracking", action="store_true",
                   help="on a model without a tracker, run the companion loop (topgimbal track) for "
                   "CAMERA_TRACK_POINT / _RECTANGLE on the visible stream (docs/tracking.md)")  # fmt: skip
    p.add_argument("--media-url", metavar="URL", help="the camera's files over HTTP (sim --media-port prints it): "
                   "CAMERA_IMAGE_CAPTURED.file_url points there")  # fmt: skip
    p.add_argument("--timeout", type=float, default=1.0, help="camera request timeout, seconds")
    for feature in FEATURES:  # each attached feature's own flags (mavlink/features/)
        feature.add_arguments(p)
    p.add_argument(
        "--silence", type=float, default=3.0, help="seconds without a frame before the camera counts as down"
    )
    p.add_argument("--max-peers", type=int, default=16, help="peers per listening link (default 16)")
    p.add_argument(
        "--signing-key",
        type=_signing_key,
        default=None,
        metavar="FILE",
        help="MAVLink 2 signing: sign what the bridge sends, refuse what is not signed with this key. FILE holds "
        "64 hex digits, 32 raw bytes, or a passphrase (its SHA-256, as MAVProxy and QGC make it)",
    )
    p.add_argument(
        "--definition-http", default="127.0.0.1:0", metavar="HOST:PORT",
        help="serve the camera definitions here (default 127.0.0.1:0, any free port; 'off': not served)",
    )  # fmt: skip
    p.add_argument("--definition-all-at-once", action="store_true",
                   help="answer CAMERA_INFORMATION at once even while a ground station downloads another "
                   "camera's definition (default: one download at a time, which MAVSDK 4.1 needs; "
                   "docs/errata.md)")  # fmt: skip
    p.add_argument("--definition-host", metavar="HOST",
                   help="the address written into the definition URI (default: the bind address; bound to all "
                   "interfaces, the address of the interface that reaches the ground station asking)")  # fmt: skip
    p.add_argument("--no-request-streams", action="store_true",
                   help="do not ask the autopilot for GLOBAL_POSITION_INT and SYSTEM_TIME on this link "
                   "(photo positions and dates; see docs/mavlink.md)")  # fmt: skip
    add_status_arguments(p)
    p.add_argument("-v", "--verbose", action="store_true", help="log every link and camera change")
    p.add_argument("--seconds", type=float, default=None, help=argparse.SUPPRESS)
    p.set_defaults(func=run)


def _signing_key(path: str) -> bytes:
    from ..links.signing import SigningKeyError, load_key

    try:
        return load_key(path)
    except SigningKeyError as exc:
        raise argparse.ArgumentTypeError(str(exc)) from None


def build_config(args: argparse.Namespace) -> object:
    from ..errors import InputError
    from ..mavlink import BridgeConfig

    url, model = getattr(args, "url", None), getattr(args, "model", None)
    if not url or not model:
        raise InputError("give the camera's --url and --model, e.g. --url udp://127.0.0.1:5000 --model C12")
    config = BridgeConfig(url=url, model=model, **config_kwargs(BridgeConfig, args))  # each field's flag
    try:
        config.check()
    except ValueError as exc:  # BridgeConfigError, EndpointError: the options given, nothing sent yet
        raise InputError(with_flags(str(exc), BridgeConfig)) from None
    return config


async def _detect(args: argparse.Namespace) -> str:
    from .model_check import detect

    return await detect(args)


def run(args: argparse.Namespace) -> int:
    import asyncio

    from ..client.jsonable import dumps
    from ..mavlink import Bridge
    from .runtime import run_server, stop_on_signals, wait_stopped

    if args.camera:  # several cameras: one component set each on shared links (mavlink_multi.py)
        return run_multi(args)
    if getattr(args, "model", None) == "auto" and getattr(args, "url", None):
        args.model = asyncio.run(_detect(args))  # --model auto: what the camera says it is
    config = build_config(args)
    logging.basicConfig(level=logging.INFO if args.verbose else logging.WARNING, format="%(levelname)s %(message)s")
    # a camera that answers as another model than --model: refused (exit 2, nothing served)
    asyncio.run(refuse_wrong_model(config.url, config.model, args.timeout))  # type: ignore[attr-defined]

    async def main() -> None:
        bridge = Bridge(config)  # type: ignore[arg-type]
        await bridge.start()
        c = bridge.config
        links = bound_links(bridge.node, bridge.addresses)
        if args.json:
            print(dumps({"mavlink_bridge": c.url, "model": c.model, "links": links, "sysid": c.sysid, "role": c.role,
                         "signing": c.signing_key is not None,
                         "definitions": {str(cam.comp.compid): cam.definition_uri for cam in bridge.cameras}}),
                  flush=True)  # fmt: skip
        else:
            print(f"mavlink bridge: {c.url} ({c.model}) <-> {links_text(links)}, system {c.sysid}, "
                  f"role {c.role}" + (", MAVLink 2 signing on" if c.signing_key else ""), flush=True)  # fmt: skip
            for cam in bridge.cameras:
                print(f"camera {cam.comp.compid} definition: {cam.definition_uri}", flush=True)
        stop = stop_on_signals()
        try:
            await serve_with_status([(f"{c.url} ({c.model})", bridge)], args, wait_stopped(stop, args.seconds))
        finally:
            await bridge.close()

    return run_server(main())
