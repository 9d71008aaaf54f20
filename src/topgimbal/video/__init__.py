"""Video: the simulator's RTSP streams rendered from its state, the console's relay, and helpers
for SDK users (`video_url`, `frames`). Needs the `video` extra (PyAV, numpy, Pillow) for anything
but the URL table in `lens.py`, so this package imports nothing heavy on its own.

See docs/video.md."""

from __future__ import annotations

from .lens import LENSES, StreamSpec, VideoError, stream_for, streams_for, video_url

__all__ = ["LENSES", "StreamSpec", "VideoError", "stream_for", "streams_for", "video_url"]
