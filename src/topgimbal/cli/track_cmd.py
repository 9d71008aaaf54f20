"""`topgimbal track`: the companion tracking loop (topgimbal.track) on a camera's video.

    topgimbal track --url udp://127.0.0.1:5000 --model C10 --video rtsp://127.0.0.1:554/stream=1 --box 0.45,0.4,0.1,0.15

Prints the loop's state once a second and a summary at the end (Ctrl-C, or `--duration`)."""

from __future__ import annotations

import argparse
import math
import sys

from ..errors import TopGimbalError
from .args import number

MAX_LATENCY_MS = 5000.0


def _box(text: str) -> tuple[float, float, float, float]:
    parts = text.split(",")
    try:
        values = tuple(float(p) for p in parts)
    except ValueError:
        raise argparse.ArgumentTypeError(f"box {text!r}: expected x,y,w,h numbers") from None
    if len(values) != 4 or not all(math.isfinite(v) for v in values):
        raise argparse.ArgumentTypeError(f"box {text!r}: expected four finite numbers x,y,w,h")
    x, y, w, h = values
    if min(values) < 0 or w <= 0 or h <= 0:
        raise argparse.ArgumentTypeError(f"box {text!r}: expected x,y,w,h with x, y at least 0 and w, h above 0")
    if max(values) <= 1 and (x + w > 1 or y + h > 1):  # fractions: within the picture (pixels: seen later)
        raise argparse.ArgumentTypeError(f"box {text!r}: as fractions of the picture, x+w and y+h at most 1")
    return x, y, w, h


def register(subparsers: argparse._SubParsersAction[argparse.ArgumentParser]) -> None:
    p = subparsers.add_parser(
        "track",
        help="companion tracking: follow what is in a box of the camera's video with the gimbal",
        description="Track a target in the camera's video with OpenCV (KCF / CSRT) and drive the gimbal's "
        "rates with a PI controller that compensates the video latency (docs/tracking.md).",
    )
    p.add_argument("--video", required=True, metavar="URL", help="the camera's RTSP stream (visible lens)")
    p.add_argument(
        "--box",
        type=_box,
        default=(0.45, 0.45, 0.1, 0.1),
        metavar="X,Y,W,H",
        help="what to track: top left and size, as fractions of the picture (all <= 1) or in pixels "
        "(default 0.45,0.45,0.1,0.1: the centre)",
    )
    p.add_argument("--tracker", choices=("kcf", "csrt"), default="kcf", help="OpenCV tracker (default kcf)")
    p.add_argument(
        "--law",
        choices=("pi", "pixel-p"),
        default="pi",
        help="pi: PI on the angle error with latency compensation (default); pixel-p: P only on raw "
        "pixels, as ArduPilot's companion example (for comparison)",
    )
    p.add_argument(
        "--latency-ms",
        type=number(low=0, high=MAX_LATENCY_MS, what="a latency"),
        default=0.0,
        metavar="MS",
        help="video latency when the pictures carry no capture stamp (the simulator's do; default 0)",
    )
    p.add_argument(
        "--duration",
        type=number(low=0, low_open=True, what="a duration"),
        metavar="S",
        help="stop after S seconds (default: until Ctrl-C)",
    )
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    import asyncio

    if not getattr(args, "url", None):
        raise TopGimbalError("no camera URL: pass --url URL (or set TOPGIMBAL_URL)")
    if not getattr(args, "model", None):
        raise TopGimbalError("track needs the camera's model: pass --model NAME")
    return asyncio.run(_track(args))


async def _track(args: argparse.Namespace) -> int:
    import asyncio

    from ..client import connect
    from ..track import CompanionTracker, TrackConfig, rtsp_frames
    from .runtime import stop_on_signals

    x, y, w, h = args.box
    async with connect(args.url, model=args.model) as cam:
        config = TrackConfig(box=(x, y, w, h), kind=args.tracker, law=args.law, box_px=max(args.box) > 1)
        tracker = CompanionTracker(cam, config)
        stop = stop_on_signals()
        run = asyncio.ensure_future(tracker.run(rtsp_frames(args.video, latency_s=args.latency_ms / 1000.0)))
        stopper = asyncio.ensure_future(stop.wait())
        elapsed = 0.0
        try:
            while not run.done():
                done, _ = await asyncio.wait({run, stopper}, timeout=1.0)
                elapsed += 1.0
                if stopper in done or (args.duration is not None and elapsed >= args.duration):
                    break
                yaw, pitch = tracker.rates_now()
                r = tracker.report
                print(
                    f"{elapsed:5.0f} s  {tracker.state:9}  rates yaw {yaw:+6.2f} pitch {pitch:+6.2f} deg/s  "
                    f"pictures {r.pictures} found {r.detections}",
                    flush=True,
                )
        finally:
            stopper.cancel()
            if not run.done():
                run.cancel()
        try:
            report = await run
        except asyncio.CancelledError:
            report = tracker.report
            report.state = tracker.state
    again = ", ".join(f"{s:.2f} s" for s in report.reacquired_after_s) or "none"
    print(
        f"topgimbal track: {report.pictures} pictures, target found in {report.detections}, lost {report.losses} "
        f"time(s), re-acquired after {again}; last state {report.state}",
        file=sys.stderr,
    )
    return 0
