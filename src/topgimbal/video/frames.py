"""Decoded pictures from a camera's RTSP stream, for users who process video in Python.

    from topgimbal.video import frames
    for picture in frames(cam.video_url("visible")):      # numpy arrays, height x width x 3 (BGR)
        cv2.imshow("camera", picture)                      # OpenCV takes BGR as it is

Needs the `video` extra (PyAV; FFmpeg is inside its wheel). Low-latency options: no input buffer,
frames as soon as they are decoded; RTP over the RTSP connection (TCP) by default, which survives
lossy links better than UDP at the price of a little delay.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Iterator
from typing import TYPE_CHECKING

from ..clock import monotonic

if TYPE_CHECKING:  # PyAV is the video extra: imported where a stream is opened
    import numpy as np
    from av.container import InputContainer
    from av.video.frame import VideoFrame

from .lens import VideoError

# Little probing: the SDP already carries the parameter sets, and every probed picture is one the
# reader starts behind by.
OPEN_OPTIONS = {
    "fflags": "nobuffer",
    "flags": "low_delay",
    "max_delay": "0",
    "analyzeduration": "100000",
    "probesize": "65536",
}


def open_stream(url: str, *, transport: str = "tcp", timeout_s: float = 5.0) -> InputContainer:
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


class LagMeter:
    """How far behind the camera a reader is: wall-clock time elapsed since the first picture
    minus stream time elapsed. Grows when pictures arrive faster than they are consumed."""

    def __init__(self, clock: Callable[[], float] = monotonic) -> None:
        self._clock = clock
        self._origin: tuple[float, float] | None = None

    def lag_s(self, frame: VideoFrame) -> float:
        if frame.time is None:
            return 0.0
        now = self._clock()
        if self._origin is None:
            self._origin = (now, float(frame.time))
        return max(0.0, (now - self._origin[0]) - (float(frame.time) - self._origin[1]))


def frames(
    url: str,
    *,
    format: str = "bgr24",
    transport: str = "tcp",
    timeout_s: float = 5.0,
    max_frames: int | None = None,
    max_lag_s: float | None = 0.25,
) -> Iterator[np.ndarray]:
    """Yield decoded pictures as numpy arrays (`format`: bgr24 for OpenCV, rgb24, gray). Ends
    when the stream ends or after `max_frames`; raises VideoError when the stream cannot be
    opened or stops sending for `timeout_s`.

    A consumer slower than the camera gets the newest pictures: those decoded more than
    `max_lag_s` behind the camera are dropped (decoding goes on; converting is what costs).
    `max_lag_s=None` yields every picture, however late.

    The arguments are checked at once (VideoError naming what is allowed), before any network:
    a bad one used to surface only after the stream was opened, as PyAV's ValueError, or not at
    all (max_frames=0 gave one picture; a negative max_lag_s dropped every picture forever)."""
    _check_frames_arguments(format, transport, timeout_s, max_frames, max_lag_s)
    return _frames(url, format, transport, timeout_s, max_frames, max_lag_s)


def _check_frames_arguments(
    format: str, transport: str, timeout_s: float, max_frames: int | None, max_lag_s: float | None
) -> None:
    import av

    if transport not in ("tcp", "udp"):
        raise VideoError(f"transport must be tcp or udp (got {transport!r})")
    try:
        av.video.format.VideoFormat(format)
    except (ValueError, TypeError):
        raise VideoError(
            f"format must be a pixel format name such as bgr24 (OpenCV), rgb24 or gray (got {format!r})"
        ) from None
    if isinstance(timeout_s, bool) or not isinstance(timeout_s, (int, float)) or not 0 < timeout_s < math.inf:
        raise VideoError(f"timeout_s must be a number of seconds above 0 (got {timeout_s!r})")
    if max_frames is not None and (isinstance(max_frames, bool) or not isinstance(max_frames, int) or max_frames < 1):
        raise VideoError(f"max_frames must be a whole number from 1, or None for no limit (got {max_frames!r})")
    if max_lag_s is not None and (
        isinstance(max_lag_s, bool) or not isinstance(max_lag_s, (int, float)) or not 0 <= max_lag_s < math.inf
    ):
        raise VideoError(f"max_lag_s must be a number of seconds from 0, or None for no limit (got {max_lag_s!r})")


def _frames(
    url: str, format: str, transport: str, timeout_s: float, max_frames: int | None, max_lag_s: float | None
) -> Iterator[np.ndarray]:
    import av

    container = open_stream(url, transport=transport, timeout_s=timeout_s)
    meter = LagMeter()
    try:
        n = 0
        for frame in container.decode(video=0):
            if max_lag_s is not None and meter.lag_s(frame) > max_lag_s:
                continue
            yield frame.to_ndarray(format=format)
            n += 1
            if max_frames is not None and n >= max_frames:
                return
    except av.FFmpegError as exc:
        raise VideoError(f"{url}: the stream failed: {exc}") from None
    finally:
        container.close()
