"""`topgimbal video relay --from rtsp://... --to udp://HOST:PORT`: a camera's RTSP stream pushed
as plain RTP over UDP (QGroundControl's port 5600), re-packetized without re-encoding
(video/rtp_push.py). `--sdp FILE` writes the session description players such as ffplay and VLC
want (QGC needs none)."""

from __future__ import annotations

import argparse
import asyncio
import logging
import sys

from .runtime import stop_on_signals, wait_stopped

SDP_WAIT_S = 10.0  # how long `--sdp` waits for the source's codec before giving up


def _rtsp(text: str) -> str:
    if not text.lower().startswith(("rtsp://", "rtsps://")):
        raise argparse.ArgumentTypeError(f"{text!r} is not an rtsp:// URL (the camera's stream)")
    return text


def _udp(text: str) -> str:
    from ..video.lens import VideoError
    from ..video.rtp_push import parse_udp_target

    try:
        parse_udp_target(text)
    except VideoError as exc:
        raise argparse.ArgumentTypeError(str(exc)) from None
    return text


def register(subparsers: argparse._SubParsersAction[argparse.ArgumentParser]) -> None:
    p = subparsers.add_parser("video", help="video tools: relay a camera's RTSP stream as RTP over UDP")
    sub = p.add_subparsers(dest="video_command", metavar="ACTION", required=True)
    r = sub.add_parser(
        "relay",
        help="push a camera's RTSP stream as RTP over UDP (QGroundControl: udp port 5600), no re-encoding",
        description="Pull an RTSP stream and push its H.264/H.265 as RTP to udp://HOST:PORT, with the "
        "parameter sets before every keyframe (a late joiner decodes from the next one). See docs/video.md.",
    )
    r.add_argument("--from", dest="source", required=True, type=_rtsp, metavar="RTSP_URL", help="the camera's stream")
    r.add_argument("--to", dest="target", required=True, type=_udp, metavar="udp://HOST:PORT", help="where to send")
    r.add_argument("--transport", choices=("tcp", "udp"), default="tcp", help="RTSP transport (default tcp)")
    r.add_argument("--sdp", metavar="FILE", help="write an SDP file describing the RTP stream (for ffplay, VLC)")
    r.add_argument("-v", "--verbose", action="store_true", help="log reconnections and send errors")
    r.add_argument("--seconds", type=float, default=None, help=argparse.SUPPRESS)
    r.set_defaults(func=run_relay)


def run_relay(args: argparse.Namespace) -> int:
    from ..video.lens import VideoError

    logging.basicConfig(level=logging.INFO if args.verbose else logging.WARNING, format="%(levelname)s %(message)s")
    try:
        from ..video.rtp_push import RtpPush
    except ImportError as exc:
        print(f"topgimbal video: error: needs the video extra (pip install 'topgimbal[video]'): {exc}", file=sys.stderr)
        return 2
    try:
        push = RtpPush(args.source, args.target, transport=args.transport).start()
    except VideoError as exc:
        print(f"topgimbal video: error: {exc}", file=sys.stderr)
        return 2

    async def main() -> int:
        print(f"video relay: {args.source} -> {args.target} (RTP, payload type 96)", flush=True)
        stop = stop_on_signals()
        if args.sdp and not await _write_sdp(push, args.sdp, stop):
            return 1
        await wait_stopped(stop, args.seconds)
        return 0

    try:
        return asyncio.run(main())
    except KeyboardInterrupt:
        return 0
    finally:
        push.stop()
        print(f"video relay: {push.stats.pictures} pictures, {push.stats.packets} packets sent", file=sys.stderr)


async def _write_sdp(push: object, path: str, stop: asyncio.Event) -> bool:
    from ..video.rtp_push import NEEDED, RtpPush, sdp_for

    assert isinstance(push, RtpPush)
    for _ in range(int(SDP_WAIT_S / 0.05)):
        if (push.codec is not None and all(k in push.params for k in NEEDED[push.codec])) or stop.is_set():
            break
        await asyncio.sleep(0.05)
    if push.codec is None:
        print(f"topgimbal video: error: no stream from {push.source_url} ({push.error or 'no answer'}): "
              "no SDP written", file=sys.stderr)  # fmt: skip
        return False
    host, port = push.target
    try:
        with open(path, "w", encoding="ascii") as f:
            f.write(sdp_for(push.codec, port, push.params, host=host))
    except OSError as exc:
        print(f"topgimbal video: error: --sdp {path}: {exc.strerror or exc}", file=sys.stderr)
        return False
    print(f"video relay: SDP in {path}", flush=True)
    return True
