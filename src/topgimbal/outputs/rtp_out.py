"""`--video-out [LENS=]udp://HOST:PORT`: the bridge pushes a lens's RTSP stream as RTP over UDP
(video/rtp_push.py: no re-encoding) to a ground station, and that lens's camera component
advertises it in VIDEO_STREAM_INFORMATION (VIDEO_STREAM_TYPE_RTPUDP, `udp://0.0.0.0:PORT`, QGC's
form: the station listens on the port) next to the RTSP stream."""

from __future__ import annotations

from ..errors import TopGimbalError
from ..protocol.streams import VideoError
from ..video.rtp_push import RtpPush, advertised_uri, parse_udp_target

__all__ = ["RtpPush", "VideoOutError", "advertised", "parse_targets"]  # RtpPush: the pusher the bridge starts

LENSES = ("visible", "thermal")
VIDEO_STREAM_TYPE_RTSP, VIDEO_STREAM_TYPE_RTPUDP = 0, 1


class VideoOutError(TopGimbalError, ValueError):
    pass


def parse_targets(specs: list[str] | None) -> dict[str, str]:
    """{lens: udp://HOST:PORT} from `[LENS=]udp://HOST:PORT` items (no lens: the visible one)."""
    out: dict[str, str] = {}
    for spec in specs or []:
        lens, eq, url = spec.partition("=")
        if not eq or lens.startswith("udp:"):
            lens, url = "visible", spec
        if lens not in LENSES:
            raise VideoOutError(f"video_out {spec!r}: the lens is one of {', '.join(LENSES)} ([LENS=]udp://HOST:PORT)")
        if lens in out:
            raise VideoOutError(f"video_out: the {lens} lens is given twice")
        try:
            parse_udp_target(url)
        except VideoError as exc:
            raise VideoOutError(f"video_out {spec!r}: {exc}") from None
        out[lens] = url
    return out


def stream_type(uri: str) -> int:
    """VIDEO_STREAM_TYPE of an advertised URI."""
    return VIDEO_STREAM_TYPE_RTPUDP if uri.startswith("udp://") else VIDEO_STREAM_TYPE_RTSP


def advertised(target: str) -> str:
    return advertised_uri(parse_udp_target(target)[1])
