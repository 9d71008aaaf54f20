"""The simulator's video: its model's RTSP streams, rendered from its state.

    video = SimVideo(sim)                       # documented ports on the simulator's loopback
    video = SimVideo(sim, port=0)               # any free port(s): tests
    await video.start(); print(video.urls)      # {"visible": "rtsp://127.0.0.1:554/stream=1", ...}
    await video.stop()

One thread per stream renders and encodes, only while someone plays the stream (and once for a
DESCRIBE, which needs the parameter sets) (numpy, Pillow and FFmpeg release the GIL for their
heavy work, so the simulator's event loop keeps its timing; bench/video.py measures it). Each
picture starts with a snapshot of the simulator taken on the simulator's own loop thread, so the
render thread never reads half-updated state.
"""

from __future__ import annotations

import asyncio
import concurrent.futures
import logging
import threading
import time
from dataclasses import dataclass
from typing import Any

from .encode import Encoder
from .lens import StreamSpec, VideoError, streams_for
from .render import Renderer
from .rtsp import RtspServer, Stream
from .snapshot import SceneState, capture

log = logging.getLogger("topgimbal.video")

DEFAULT_FPS = 30.0
MAX_FPS = 60.0
SNAPSHOT_TIMEOUT_S = 1.0


@dataclass(frozen=True)
class VideoOptions:
    host: str = "127.0.0.1"
    port: int | None = None  # None: documented ports; 0: free ports; N: the first lens's port, others follow
    fps: float = DEFAULT_FPS
    size: tuple[int, int] | None = None  # visible picture size (thermal keeps its own)
    codec: str | None = None  # force "h264" / "h265" on every stream (else the model's setting)
    bitrate_kbps: int | None = None

    def __post_init__(self) -> None:
        if not 1.0 <= self.fps <= MAX_FPS:
            raise VideoError(f"fps must be within 1..{MAX_FPS:g} (got {self.fps:g})")
        if self.size is not None:
            w, h = self.size
            if not (64 <= w <= 3840 and 48 <= h <= 2160) or w % 2 or h % 2:
                raise VideoError(f"picture size must be even, 64x48..3840x2160 (got {w}x{h})")
        if self.codec not in (None, "h264", "h265"):
            raise VideoError(f"codec must be h264 or h265 (got {self.codec!r})")


def plan_ports(specs: tuple[StreamSpec, ...], port: int | None) -> dict[int, int]:
    """Documented port -> port to bind. An override keeps the documented spacing (554/555 ->
    N/N+1); 0 gives each documented port its own free port."""
    documented = sorted({s.port for s in specs})
    if port is None:
        return {p: p for p in documented}
    if port == 0:
        return {p: 0 for p in documented}
    return {p: port + (p - documented[0]) for p in documented}


class SimVideo:
    def __init__(self, sim: Any, options: VideoOptions | None = None, **kw: Any) -> None:
        self.sim = sim
        self.options = options or VideoOptions(**kw)
        self.specs = streams_for(sim.model)
        self.servers: list[RtspServer] = []
        self.streams: dict[str, Stream] = {}
        self.urls: dict[str, str] = {}
        self._workers: list[_Worker] = []
        self._loop: asyncio.AbstractEventLoop | None = None

    def _codec(self, spec: StreamSpec) -> str:
        if self.options.codec:
            return self.options.codec
        ent = self.sim.settings.get("ENT")
        if (
            spec.codec_setting
            and ent
            and ent.get("stream") == spec.codec_setting
            and ent.get("codec") in ("h264", "h265")
        ):
            return str(ent["codec"])
        return spec.codec

    def _bitrate(self) -> int:
        if self.options.bitrate_kbps:
            return self.options.bitrate_kbps
        s = self.sim.settings
        for ident in ("VOM", "BIT"):
            if ident in s and s[ident].get("bitrate_kbps"):
                return int(s[ident]["bitrate_kbps"])
        return 4000

    async def start(self) -> SimVideo:
        self._loop = asyncio.get_running_loop()
        ports = plan_ports(self.specs, self.options.port)
        try:
            by_port: dict[int, list[tuple[StreamSpec, Stream]]] = {}
            for spec in self.specs:
                worker = _Worker(self, spec)
                stream = Stream(spec.path, self._codec(spec), on_keyframe_wanted=worker.want_keyframe)
                worker.stream = stream
                self.streams[spec.lens] = stream
                self._workers.append(worker)
                by_port.setdefault(spec.port, []).append((spec, stream))
            for documented, items in by_port.items():
                server = RtspServer(self.options.host, ports[documented], [s for _, s in items])
                try:
                    await server.start()
                except OSError as exc:
                    raise VideoError(
                        f"cannot serve RTSP on {self.options.host}:{ports[documented]} ({exc.strerror or exc}); "
                        "ports below 1024 need root: give another port (--video-port N, or 0 for any free one)"
                    ) from None
                self.servers.append(server)
                for spec, _ in items:
                    self.urls[spec.lens] = server.url(spec.path)
            for w in self._workers:
                w.start()
        except BaseException:
            await self.stop()
            raise
        return self

    async def stop(self) -> None:
        for w in self._workers:
            w.stop()
        for s in self.servers:
            await s.close()
        for w in self._workers:
            await asyncio.get_running_loop().run_in_executor(None, w.join)
        self._workers, self.servers = [], []

    # -- called from the worker threads --------------------------------------------------------------

    def snapshot(self, frame: int) -> SceneState | None:
        """A state snapshot taken on the simulator's loop (None when the loop is gone or stuck)."""
        loop = self._loop
        if loop is None or loop.is_closed():
            return None
        fut: concurrent.futures.Future[SceneState] = concurrent.futures.Future()

        def take() -> None:
            try:
                fut.set_result(capture(self.sim.device, frame))
            except BaseException as exc:  # hand it to the worker
                fut.set_exception(exc)

        try:
            loop.call_soon_threadsafe(take)
            return fut.result(SNAPSHOT_TIMEOUT_S)
        except (RuntimeError, concurrent.futures.TimeoutError):
            return None

    def publish(self, stream: Stream, units: list[Any]) -> None:
        loop = self._loop
        if loop is None or loop.is_closed() or not units:
            return

        def deliver() -> None:
            for u in units:
                stream.publish(u)

        try:
            loop.call_soon_threadsafe(deliver)
        except RuntimeError:
            pass  # the loop closed while we encoded


class _Worker:
    """Renders and encodes one stream at the frame rate, in its own thread."""

    def __init__(self, video: SimVideo, spec: StreamSpec) -> None:
        self.video = video
        self.spec = spec
        self.stream: Stream | None = None
        opts = video.options
        self.size = opts.size if (opts.size and spec.lens == "visible") else spec.size
        self.fps = opts.fps
        self._stop = threading.Event()
        self._key = threading.Event()
        self._thread = threading.Thread(target=self._run, name=f"topgimbal-video-{spec.lens}", daemon=True)
        self.frames = 0
        self.skipped = 0

    def start(self) -> None:
        self._thread.start()

    def stop(self) -> None:
        self._stop.set()

    def join(self) -> None:
        if self._thread.is_alive():
            self._thread.join(5)

    def want_keyframe(self) -> None:
        self._key.set()

    def _run(self) -> None:
        assert self.stream is not None
        w, h = self.size
        try:
            renderer = Renderer(self.spec.lens, w, h, self.spec.hfov_deg)
            encoder = Encoder(self.stream.codec, w, h, self.fps, bitrate_kbps=self.video._bitrate())
        except Exception:
            log.exception("video %s: cannot start the encoder", self.spec.lens)
            return
        period = 1.0 / self.fps
        next_t = time.monotonic()
        try:
            while not self._stop.is_set():
                now = time.monotonic()
                if now < next_t:
                    self._stop.wait(next_t - now)
                    continue
                if now - next_t > period:
                    # Behind (a busy machine): drop the missed frames instead of bursting them.
                    self.skipped += int((now - next_t) / period)
                    next_t = now
                next_t += period
                if not self.stream.receivers and not self._key.is_set():
                    # Nobody watches: render nothing (a DESCRIBE or PLAY asks for a keyframe).
                    self._key.wait(period)
                    continue
                state = self.video.snapshot(self.frames)
                if state is None:
                    continue
                picture = renderer.render(state)
                force = self._key.is_set()
                self._key.clear()
                units = encoder.encode(picture, now, keyframe=force)
                self.frames += 1
                self.video.publish(self.stream, units)
        except Exception:
            log.exception("video %s: the render thread failed", self.spec.lens)
        finally:
            encoder.close()
