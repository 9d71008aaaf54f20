"""The console's video relay: one camera stream (RTSP, real or simulated) to any number of
browsers as MJPEG (multipart JPEG over HTTP: one `<img>`, no script, no player buffer).

A reader thread opens the stream with PyAV only while someone watches, decodes every picture,
and JPEG-encodes the newest one for the viewers; viewers that are slower than the camera skip
pictures (the relay keeps one picture, never a queue). When the stream fails or stops, the state
says so and the reader tries again every RETRY_S. Bounds: MAX_VIEWERS per stream (more get 503;
the last OPERATOR_RESERVED places go only to the console's own page, so other clients cannot
lock the operator out;
a viewer that takes no picture for webconsole.VIEWER_STALL_S is dropped), one JPEG buffered, MAX_FPS pictures per second to the browsers, and at most MAX_LAG_S behind
the camera (a relay that falls further behind reopens the stream).
"""

from __future__ import annotations

import asyncio
import concurrent.futures
import logging
import threading
from collections.abc import AsyncGenerator
from fractions import Fraction
from typing import TYPE_CHECKING, Any

from ..clock import monotonic

if TYPE_CHECKING:  # PyAV is the video extra: imported by the reader thread
    from av.container import InputContainer
    from av.video.codeccontext import VideoCodecContext
    from av.video.frame import VideoFrame

from .lens import VideoError

log = logging.getLogger("topgimbal.video.relay")

MAX_VIEWERS = 8
OPERATOR_RESERVED = 2  # of MAX_VIEWERS: only for the console's own page (webconsole.py says which)
MAX_FPS = 30.0
RETRY_S = 1.0
IDLE_CLOSE_S = 5.0  # keep the camera stream open this long after the last viewer left
JPEG_QMAX = 6  # FFmpeg's JPEG quantiser ceiling (2 best .. 31 worst); 6 looks like quality ~80
READ_TIMEOUT_S = 3.0
# Behind the camera by more than this (pictures arrive faster than this machine decodes them):
# stop JPEG-encoding until caught up, and past MAX_LAG_S reopen the stream instead of falling
# further behind (the operator wants the newest picture, not a backlog).
CATCH_UP_LAG_S = 0.15
MAX_LAG_S = 1.0


class Relay:
    """One stream. `state` is "idle", "connecting", "playing" or "reconnecting" (+ `error`)."""

    def __init__(self, name: str, url: str) -> None:
        self.name = name
        self.url = url
        self.state = "idle"
        self.error: str | None = None
        self.viewers = 0
        self.size: tuple[int, int] | None = None
        self.pictures = 0
        self.jpeg: bytes | None = None
        self.jpeg_seq = 0
        self._loop: asyncio.AbstractEventLoop | None = None
        self._cond: asyncio.Condition | None = None
        self._thread: threading.Thread | None = None
        self._stop = threading.Event()
        self._last_viewer = 0.0
        self.closed = False
        self.lag_resets = 0
        self._encoder: VideoCodecContext | None = None
        self._pending: concurrent.futures.Future[None] | None = (
            None  # the picture handed to the loop, until it has taken it
        )

    def status(self) -> dict[str, Any]:
        return {
            "state": self.state,
            "error": self.error,
            "viewers": self.viewers,
            "size": list(self.size) if self.size else None,
            "pictures": self.pictures,
            "lag_resets": self.lag_resets,
        }

    # -- viewers (event loop) ------------------------------------------------------------------------

    async def pictures_for_viewer(self, *, operator: bool = False) -> AsyncGenerator[bytes, None]:
        """JPEG pictures as they come, newest first, for one viewer. Raises RelayFullError.
        `operator`: the console's own page, which may also take the OPERATOR_RESERVED places."""
        limit = MAX_VIEWERS if operator else MAX_VIEWERS - OPERATOR_RESERVED
        if self.viewers >= limit:
            log.warning("video %s: refusing a viewer: %d already (the limit%s)", self.name, self.viewers,
                        "" if operator else f"; {OPERATOR_RESERVED} more are kept for the console's own page")  # fmt: skip
            raise RelayFullError(f"{self.viewers} viewers already watch the {self.name} stream"
                                 + ("" if operator else f" ({OPERATOR_RESERVED} places are kept for the console's page)"))  # fmt: skip
        self._loop = asyncio.get_running_loop()
        if self._cond is None:
            self._cond = asyncio.Condition()
        self.viewers += 1
        self._ensure_reader()
        seen = -1
        try:
            while True:
                async with self._cond:
                    await self._cond.wait_for(lambda seen=seen: self.jpeg_seq != seen or self.closed)  # type: ignore[misc]
                if self.closed:
                    return
                seen = self.jpeg_seq
                if self.jpeg is not None:
                    yield self.jpeg
        finally:
            self.viewers -= 1
            self._last_viewer = monotonic()

    def _ensure_reader(self) -> None:
        if self._thread is not None and self._thread.is_alive():
            return
        self._stop.clear()
        self._thread = threading.Thread(target=self._read_loop, name=f"topgimbal-relay-{self.name}", daemon=True)
        self._thread.start()

    async def _publish(self, jpeg: bytes) -> None:
        assert self._cond is not None
        async with self._cond:
            self.jpeg = jpeg
            self.jpeg_seq += 1
            self._cond.notify_all()

    async def close(self) -> None:
        """Stop reading and end every viewer's pictures (their responses finish)."""
        self._stop.set()
        self.closed = True
        if self._cond is not None:
            async with self._cond:
                self._cond.notify_all()

    # -- the reader (thread) -------------------------------------------------------------------------

    def _read_loop(self) -> None:
        from .frames import open_stream

        while not self._stop.is_set():
            if self.viewers == 0 and monotonic() - self._last_viewer > IDLE_CLOSE_S:
                self.state = "idle"
                return
            self.state = "connecting" if self.pictures == 0 else "reconnecting"
            try:
                container = open_stream(self.url, timeout_s=READ_TIMEOUT_S)
            except Exception as exc:
                self._failed(exc)
                continue
            lag_resets = self.lag_resets
            try:
                self._pump(container)
            except Exception as exc:
                self._failed(exc)
            finally:
                container.close()
            if not self._stop.is_set() and self.viewers and self.lag_resets == lag_resets:
                self._failed(None)

    def _failed(self, exc: Exception | None) -> None:
        self.error = str(exc) if exc else "the stream ended"
        if self.state != "reconnecting":
            log.warning("video %s: %s; retrying every %.0f s", self.name, self.error, RETRY_S)
        self.state = "reconnecting"
        self._stop.wait(RETRY_S)

    def _pump(self, container: InputContainer) -> None:
        from .frames import LagMeter

        min_gap = 1.0 / MAX_FPS
        last = 0.0
        meter = LagMeter()
        for frame in container.decode(video=0):
            if self._stop.is_set():
                return
            if self.viewers == 0 and monotonic() - self._last_viewer > IDLE_CLOSE_S:
                return
            self.state, self.error = "playing", None
            self.size = (frame.width, frame.height)
            self.pictures += 1
            now = monotonic()
            lag = meter.lag_s(frame)
            if lag > MAX_LAG_S:
                self.lag_resets += 1
                log.warning("video %s: %.1f s behind the camera (this machine is too busy): reopening", self.name, lag)
                return
            if lag > CATCH_UP_LAG_S or now - last < min_gap:
                continue
            last = now
            pending = self._pending
            if pending is not None and not pending.done():
                continue  # the loop has not taken the last picture yet: never queue more than one
            jpeg = self._jpeg(frame)
            loop = self._loop
            if loop is not None and not loop.is_closed():
                self._pending = asyncio.run_coroutine_threadsafe(self._publish(jpeg), loop)

    def _jpeg(self, frame: VideoFrame) -> bytes:
        """JPEG straight from the decoded YUV picture with FFmpeg's encoder: 2.5x cheaper than
        converting to RGB for Pillow (bench/video.py)."""
        import av

        if self._encoder is None or (self._encoder.width, self._encoder.height) != (frame.width, frame.height):
            enc = av.CodecContext.create("mjpeg", "w")
            enc.width, enc.height = frame.width, frame.height
            enc.pix_fmt = "yuvj420p"
            enc.time_base = Fraction(1, 90000)
            enc.qmin, enc.qmax = 2, JPEG_QMAX
            enc.open()
            self._encoder = enc
        pic = frame.reformat(format="yuvj420p")
        pic.pts = None
        return b"".join(bytes(p) for p in self._encoder.encode(pic))


class RelayFullError(VideoError):
    """Too many viewers on one stream."""
