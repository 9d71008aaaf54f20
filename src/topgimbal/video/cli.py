"""`topgimbal sim --video ...`: the options, and starting the streams next to a simulator."""

from __future__ import annotations

import argparse
import ipaddress
import sys
from typing import TYPE_CHECKING

if TYPE_CHECKING:
    from ..sim.simulator import Simulator
    from .simvideo import SimVideo

from .lens import VideoError

LOOPBACK = ("127.0.0.1", "::1", "localhost")


def is_loopback(host: str) -> bool:
    """Any loopback address (all of 127.0.0.0/8, ::1) or `localhost`: several simulated cameras
    can then use their documented ports side by side (127.0.0.2:554, 127.0.0.3:554...)."""
    if host == "localhost":
        return True
    try:
        return ipaddress.ip_address(host.strip("[]")).is_loopback
    except ValueError:
        return False


def _size(text: str) -> tuple[int, int]:
    w, sep, h = text.lower().partition("x")
    if not sep or not w.isdigit() or not h.isdigit():
        raise argparse.ArgumentTypeError(f"{text!r} is not WIDTHxHEIGHT (e.g. 1280x720)")
    return int(w), int(h)


def _port(text: str) -> int:
    if not (text.isascii() and text.isdigit()) or not 0 <= int(text) <= 65535:
        raise argparse.ArgumentTypeError(f"{text!r} is not a port: give 0..65535 (0 picks free ports)")
    return int(text)


def add_arguments(p: argparse.ArgumentParser) -> None:
    g = p.add_argument_group("video (needs the video extra: pip install 'topgimbal[video]')")
    g.add_argument("--video", action="store_true", help="serve the model's RTSP streams, rendered from the simulation")
    add_video_port_argument(
        g, "RTSP port instead of the documented one (554; SkyDroid thermal 555 becomes N+1); 0 picks free ports"
    )
    g.add_argument("--video-host", metavar="ADDR", help="RTSP address (default: the simulator's loopback address)")
    g.add_argument("--video-fps", type=float, default=30.0, metavar="FPS", help="frame rate (default 30)")
    g.add_argument("--video-size", type=_size, metavar="WxH", help="visible picture size (default 1280x720)")
    g.add_argument("--video-codec", choices=("h264", "h265"), help="force a codec (default: the model's setting)")


def add_video_port_argument(parser: argparse.ArgumentParser | argparse._ArgumentGroup, help_text: str) -> None:
    """`--video-port N`: the first RTSP port when not the model's (the simulator's and the bridge's)."""
    parser.add_argument("--video-port", type=_port, metavar="N", help=help_text)


def wants_video(args: argparse.Namespace) -> bool:
    return bool(getattr(args, "video", False))


def video_host(args: argparse.Namespace, sim: Simulator) -> str:
    host = getattr(args, "video_host", None)
    if host is None:
        addrs = [a for kind in ("udp", "tcp") for a in sim.addresses.get(kind, [])]
        host = addrs[0][0] if addrs and is_loopback(addrs[0][0]) else "127.0.0.1"
    if not is_loopback(host) and not getattr(args, "allow_any_address", False):
        raise VideoError(f"the simulator's video listens on loopback only (got {host!r}; use 127.0.0.0/8 or ::1)")
    return str(host)


async def start(sim: Simulator, args: argparse.Namespace) -> SimVideo:
    """Start the simulator's streams as the arguments say; prints one URL per lens."""
    try:
        from .simvideo import SimVideo, VideoOptions
    except ImportError as exc:
        raise VideoError(f"--video needs the video extra (pip install 'topgimbal[video]'): {exc}") from None
    opts = VideoOptions(
        host=video_host(args, sim),
        port=args.video_port,
        fps=args.video_fps,
        size=args.video_size,
        codec=args.video_codec,
    )
    video = await SimVideo(sim, opts).start()
    for lens, url in video.urls.items():
        print(url, flush=True)
        print(f"topgimbal sim: {lens} video at {url} ({video.streams[lens].codec})", file=sys.stderr)
    return video


# -- `--media DIR`: the camera's card (media.py, media_http.py) -----------------------------------


def _mib(text: str) -> int:
    if not (text.isascii() and text.isdigit()) or int(text) < 1:
        raise argparse.ArgumentTypeError(f"{text!r} is not a size in MiB: give a whole number >= 1")
    return int(text)


def add_media_arguments(p: argparse.ArgumentParser) -> None:
    g = p.add_argument_group("media (the camera's files; needs the video extra)")
    g.add_argument("--media", metavar="DIR", help="store each photo (JPEG with EXIF/XMP) and recording (MP4) in DIR")
    g.add_argument(
        "--media-port", type=_port, metavar="N", help="serve DIR over HTTP on loopback port N (0: a free port)"
    )
    g.add_argument("--media-max-mib", type=_mib, default=256, metavar="MIB",
                   help="size cap of DIR; the oldest files are dropped (default 256)")  # fmt: skip


class Media:
    """The media store and its HTTP server, started and stopped together."""

    def __init__(self, store: object, server: object | None) -> None:
        self.store, self.server = store, server

    async def stop(self) -> None:
        from .media import MediaStore
        from .media_http import MediaServer

        if isinstance(self.server, MediaServer):
            self.server.stop()
        if isinstance(self.store, MediaStore):
            await self.store.stop()


async def start_media(sim: Simulator, args: argparse.Namespace) -> Media | None:
    """Start `--media DIR` (and `--media-port`) as the arguments say; prints the HTTP URL."""
    directory = getattr(args, "media", None)
    if directory is None:
        if getattr(args, "media_port", None) is not None:
            raise VideoError("--media-port needs --media DIR")
        return None
    try:
        from .media import MediaStore
        from .media_http import MediaServer
    except ImportError as exc:
        raise VideoError(f"--media needs the video extra (pip install 'topgimbal[video]'): {exc}") from None
    try:
        store = MediaStore(sim, directory, max_bytes=args.media_max_mib * 1024 * 1024).start()
    except OSError as exc:
        raise VideoError(f"--media {directory}: {exc.strerror or exc}") from None
    server = None
    if args.media_port is not None:
        server = MediaServer(directory, video_host(args, sim), args.media_port).start()
        print(server.url, flush=True)
        print(f"topgimbal sim: media files at {server.url}", file=sys.stderr)
    print(f"topgimbal sim: photos and recordings go to {directory}", file=sys.stderr)
    return Media(store, server)
