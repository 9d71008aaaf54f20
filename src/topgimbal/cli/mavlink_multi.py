"""`topgimbal mavlink --camera NAME=URL,MODEL[,OPTION=VALUE...] ...`: several cameras behind one
bridge (mavlink/multi.py allocates the component ids; docs/fleet.md). Each camera takes its own
video options (video-url=URL, video-port=N, video-out=[LENS=]udp://HOST:PORT, each repeatable
where it may be); the one-camera options that cannot apply to several are refused."""

from __future__ import annotations

import argparse
import asyncio
import logging
import os
import sys
from dataclasses import dataclass, field
from typing import Any

from .config_args import config_kwargs, with_flags
from .mavlink_status import bound_links, links_text, serve_with_status
from .model_guard import check_cameras
from .runtime import run_server, stop_on_signals, wait_stopped
from .zenoh_cmd import camera_arg

CAMERA_FORM = "NAME=URL,MODEL|auto[,video-url=URL][,video-port=N][,video-out=[LENS=]udp://HOST:PORT]"
# Per-camera options: key -> (BridgeConfig field, repeatable)
CAMERA_OPTIONS = {"video-url": ("video_urls", True), "video-port": ("video_port", False),
                  "video-out": ("video_out", True)}  # fmt: skip
# One-camera options and why they do not apply with --camera (their value when not given is None).
NOT_WITH_CAMERAS = {
    "compid": "--compid (gimbal ids are allocated in order: 154, 171..)",
    "camera_compid": "--camera-compid (camera ids are allocated in order from 100)",
    "video_url": "--video-url (give video-url=URL in each --camera)",
    "video_port": "--video-port (give video-port=N in each --camera)",
    "video_out": "--video-out (give video-out=[LENS=]udp://HOST:PORT in each --camera)",
    "media_url": "--media-url (one camera's files)",
}


@dataclass
class CameraWithOptions:
    name: str
    url: str
    model: str
    options: dict[str, Any] = field(default_factory=dict)


def camera_with_options(text: str) -> CameraWithOptions:
    """NAME=URL,MODEL followed by this camera's options (trailing `key=value` items)."""
    parts = text.split(",")
    options: dict[str, Any] = {}
    while len(parts) > 2 and parts[-1].partition("=")[0].strip() in CAMERA_OPTIONS:
        key, _, value = parts.pop().partition("=")
        name, repeatable = CAMERA_OPTIONS[key.strip()]
        value = value.strip()
        if name == "video_port":
            if not (value.isascii() and value.isdigit()) or not 1 <= int(value) <= 65535:
                raise argparse.ArgumentTypeError(f"{text!r}: video-port={value!r}: expected 1..65535")
            if name in options:
                raise argparse.ArgumentTypeError(f"{text!r}: video-port given twice")
            options[name] = int(value)
        elif repeatable:
            options.setdefault(name, []).insert(0, value)  # read from the end: keep the order given
    auto = len(parts) > 1 and parts[-1].strip().lower() == "auto"
    if auto:  # MODEL=auto: asked of the camera at start (model_guard.check_cameras); the rest checked as usual
        parts[-1] = "C12"
    spec = camera_arg(",".join(parts))
    model = "auto" if auto else spec.model  # type: ignore[attr-defined]
    return CameraWithOptions(spec.name, spec.url, model, options)  # type: ignore[attr-defined]


# The options every camera of a --camera bridge shares, as BridgeConfig fields (from their flags)
SHARED = ("role", "attitude_hz", "stream_hz", "range_hz", "timeout_s", "silence_s", "signing_key", "definition_http",
          "definition_host", "request_streams", "terrain")  # fmt: skip


def add_fleet_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("--camera", action="append", type=camera_with_options, default=[], metavar=CAMERA_FORM,
                   help="several cameras on one bridge (repeatable, instead of --url/--model): gimbals 154, 171.., "
                   "cameras 100.. allocated in order; each with its own video options")  # fmt: skip


def refused_with_cameras(args: argparse.Namespace) -> list[str]:
    """The one-camera options given with --camera (none of them applies to several cameras)."""
    return [why for key, why in NOT_WITH_CAMERAS.items() if getattr(args, key, None) is not None]


def run_multi(args: argparse.Namespace) -> int:
    from ..client.jsonable import dumps
    from ..mavlink.multi import MultiBridge

    if getattr(args, "url", None) and args.url != os.environ.get("TOPGIMBAL_URL"):
        print("topgimbal mavlink: error: give either --url/--model (one camera) or --camera (several)", file=sys.stderr)
        return 2
    refused = refused_with_cameras(args)
    if refused:
        print(f"topgimbal mavlink: error: with --camera, {'; '.join(refused)} does not apply: "
              f"each camera takes {CAMERA_FORM}", file=sys.stderr)  # fmt: skip
        return 2
    logging.basicConfig(level=logging.INFO if args.verbose else logging.WARNING, format="%(levelname)s %(message)s")
    # MODEL auto resolved; a camera that answers as another MODEL refused (exit 2, nothing served)
    for c, model in zip(args.camera, asyncio.run(check_cameras(args.camera, args.timeout, auto=True)), strict=True):
        c.model = model
    cameras = [(c.name, c.url, c.model) for c in args.camera]
    from ..mavlink import BridgeConfig

    given = config_kwargs(BridgeConfig, args)  # each field's flag
    common = {k: v for k, v in given.items() if k in SHARED}
    # --cot: every camera its own CoT uid and callsign, from its name (one marker per camera on the map)
    cot = getattr(args, "cot", None)
    tls = given["cot_tls"]
    own = [{**c.options, **({"cot": cot, "cot_name": c.name, "cot_tls": tls} if cot else {})} for c in args.camera]
    try:
        multi = MultiBridge(cameras, endpoints=list(args.mavlink), sysid=args.sysid, cameras_wanted=not args.no_camera,
                            thermal=not args.no_thermal, max_peers=args.max_peers, per_camera=own, **common)  # fmt: skip
    except ValueError as exc:  # BridgeConfigError, CotConfigError, DemError: the options given, nothing sent yet
        print(f"topgimbal mavlink: error: {with_flags(str(exc), BridgeConfig)}", file=sys.stderr)
        return 2

    async def main() -> None:
        await multi.start()
        links = bound_links(multi.node, multi.addresses)
        if getattr(args, "json", False):
            cams = [{"name": a.name, "url": a.url, "model": a.model, "gimbal": a.gimbal_compid,
                     "cameras": a.camera_compids, "video_out": [p.target_url for p in b.video_pushes]}
                    for b, a in zip(multi.bridges, multi.allocations, strict=True)]  # fmt: skip
            print(dumps({"mavlink_bridge": cams, "links": links, "sysid": args.sysid}), flush=True)
        else:
            parts = "; ".join(f"{a.name} ({a.model}): gimbal {a.gimbal_compid}, cameras "
                              f"{','.join(map(str, a.camera_compids)) or 'none'}" for a in multi.allocations)  # fmt: skip
            print(f"mavlink bridge: {len(cameras)} cameras <-> {links_text(links)}, system {args.sysid}: {parts}",
                  flush=True)  # fmt: skip
            for b, a in zip(multi.bridges, multi.allocations, strict=True):
                for push in b.video_pushes:
                    print(f"{a.name} {push.name} video: RTP to {push.target_url}", flush=True)
        stop = stop_on_signals()
        named = [(f"{a.name} ({a.model})", b) for b, a in zip(multi.bridges, multi.allocations, strict=True)]
        try:
            await serve_with_status(named, args, wait_stopped(stop, args.seconds))
        finally:
            await multi.close()

    return run_server(main())
