"""H.264 / H.265 encoding with PyAV (its wheels bundle FFmpeg with libx264 and libx265).

Settings chosen for a live picture: no B-frames, zero-latency tuning (one frame in, one access unit
out), a keyframe every `gop` frames with the parameter sets repeated in front of each (a client
that joins mid-stream can start there), one thread (its CPU cost is bounded and measurable).
"""

from __future__ import annotations

from dataclasses import dataclass
from fractions import Fraction

import av
import numpy as np
from av.video.codeccontext import VideoCodecContext
from PIL import Image

from .lens import VideoError

CODECS = {"h264": "libx264", "h265": "libx265"}


@dataclass(frozen=True)
class AccessUnit:
    """One encoded picture in Annex B form (start codes between NAL units)."""

    data: bytes
    keyframe: bool
    pts_s: float  # capture time, seconds (monotonic)
    codec: str = "h264"


class Encoder:
    def __init__(
        self, codec: str, width: int, height: int, fps: float, *, bitrate_kbps: int = 4000, gop: int | None = None
    ) -> None:
        if codec not in CODECS:
            raise VideoError(f"codec must be one of {', '.join(CODECS)} (got {codec!r})")
        self.codec = codec
        self.width, self.height, self.fps = width, height, fps
        gop = max(1, int(gop or round(fps)))
        ctx = av.CodecContext.create(CODECS[codec], "w")
        if not isinstance(ctx, VideoCodecContext):  # CODECS names video encoders only
            raise VideoError(f"{CODECS[codec]} is not a video encoder in this FFmpeg")
        ctx.width, ctx.height = width, height
        ctx.pix_fmt = "yuv420p"
        ctx.time_base = Fraction(1, 90000)
        ctx.framerate = Fraction(round(fps * 1000), 1000)
        ctx.bit_rate = bitrate_kbps * 1000
        ctx.gop_size = gop
        ctx.max_b_frames = 0
        ctx.thread_count = 1
        if codec == "h264":
            ctx.options = {
                "preset": "ultrafast",
                "tune": "zerolatency",
                "x264-params": f"keyint={gop}:min-keyint={gop}:scenecut=0:repeat-headers=1:bframes=0",
            }
            ctx.profile = "Constrained Baseline"
        else:
            ctx.options = {
                "preset": "ultrafast",
                "tune": "zerolatency",
                "x265-params": f"keyint={gop}:min-keyint={gop}:scenecut=0:repeat-headers=1:bframes=0:log-level=error:pools=1:frame-threads=1",
            }
        ctx.open()
        self._ctx = ctx
        self._n = 0

    def encode(self, picture: Image.Image | np.ndarray, pts_s: float, *, keyframe: bool = False) -> list[AccessUnit]:
        """Encode one picture: RGB (an image or an array), or a Pillow "YCbCr" image holding
        limited-range BT.601 values (the renderer's YCbCr mode: only the chroma is subsampled
        here); `keyframe` forces an IDR (a new receiver starts at once)."""
        if isinstance(picture, Image.Image) and picture.mode == "YCbCr":
            frame = yuv420_frame(picture)
        else:
            frame = av.VideoFrame.from_ndarray(np.asarray(picture), format="rgb24").reformat(format="yuv420p")
        if keyframe:
            frame.pict_type = av.video.frame.PictureType.I
        frame.pts = round(pts_s * 90000)
        frame.time_base = Fraction(1, 90000)
        self._n += 1
        return [self._unit(p, pts_s) for p in self._ctx.encode(frame)]

    def _unit(self, packet: av.Packet, pts_s: float) -> AccessUnit:
        return AccessUnit(bytes(packet), bool(packet.is_keyframe), pts_s, self.codec)

    def close(self) -> None:
        try:
            self._ctx.encode(None)
        except Exception:  # flushing a live encoder at shutdown: nothing to keep
            pass


def yuv420_frame(picture: Image.Image) -> av.VideoFrame:
    """A yuv420p frame from a Pillow "YCbCr" image (even sizes): Y as it is, Cb and Cr averaged
    over 2x2 pixels by Pillow's `reduce` (C code). Never through numpy's view of the whole image:
    for a YCbCr image that conversion alone costs ~7 ms per 720p picture; this costs ~2.5 ms."""
    w, h = picture.size
    if h % 2 or w % 2:
        raise VideoError(f"picture size must be even for 4:2:0 video (got {w}x{h})")
    n, q = w * h, w * h // 4
    flat = np.empty(n + 2 * q, np.uint8)
    flat[:n] = np.frombuffer(picture.getchannel(0).tobytes(), np.uint8)
    small = picture.reduce(2)
    flat[n : n + q] = np.frombuffer(small.getchannel(1).tobytes(), np.uint8)
    flat[n + q :] = np.frombuffer(small.getchannel(2).tobytes(), np.uint8)
    return av.VideoFrame.from_ndarray(flat.reshape(h * 3 // 2, w), format="yuv420p")
