"""Decoded pictures from a camera's RTSP stream, for users who process video in Python.

    from topgimbal.video import frames
    for picture in frames(cam.video_url("visible")):      # numpy arrays, height x width x 3 (BGR)
        cv2.imshow("camera", picture)                      # OpenCV takes BGR as it is

Needs the `video` extra (PyAV; FFmpeg is inside its wheel). Low-latency options: no input buffer,
frames as soon as they are decoded; RTP over the RTSP connection (TCP) by default, which survives
lossy links better than UDP at the price of a little delay.
"""

from __future__ import annotations

from collections.abc import Iterator
from typing import Any

from .lens import VideoError

OPEN_OPTIONS = {"fflags": "nobuffer", "flags": "low_delay", "max_delay": "0"}


def open_stream(url: str, *, transport: str = "tcp", timeout_s: float = 5.0) -> Any:
    """An opened PyAV container for an RTSP URL (the caller closes it)."""
    import av

    if transport not in ("tcp", "udp"):
        raise VideoError(f"transport must be tcp or udp (got {transport!r})")
    try:
        container = av.open(url, options={**OPEN_OPTIONS, "rtsp_transport": transport}, timeout=timeout_s)
    except av.FFmpegError as exc:
        raise VideoError(f"cannot open {url}: {exc}") from None
    for s in container.streams.video:
        # Frame threads hold (threads - 1) pictures back; slice threads hold none.
        s.thread_type = "SLICE"
    return container


def frames(
    url: str,
    *,
    format: str = "bgr24",
    transport: str = "tcp",
    timeout_s: float = 5.0,
    max_frames: int | None = None,
) -> Iterator[Any]:
    """Yield decoded pictures as numpy arrays (`format`: bgr24 for OpenCV, rgb24, gray). Ends
    when the stream ends or after `max_frames`; raises VideoError when the stream cannot be
    opened or stops sending for `timeout_s`."""
    import av

    container = open_stream(url, transport=transport, timeout_s=timeout_s)
    try:
        for n, frame in enumerate(container.decode(video=0), 1):
            yield frame.to_ndarray(format=format)
            if max_frames is not None and n >= max_frames:
                return
    except av.FFmpegError as exc:
        raise VideoError(f"{url}: the stream failed: {exc}") from None
    finally:
        container.close()
