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

Streams, paths, ports, fields of view and the codec setting come from the model profile (through
`lens.streams_for`). A codec change (TOPOTEK `ENT`) takes effect on a running stream as on a
camera that restarts its encoder: the stream's players are disconnected (an RTP session cannot
change its payload format), the encoder is rebuilt in the render thread, and the next DESCRIBE
gives the new codec's SDP; players that reconnect (ffplay, VLC, the console's relay) go on.
"""

from __future__ import annotations

import asyncio
import concurrent.futures
import contextlib
import logging
import threading
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

from ..clock import monotonic

if TYPE_CHECKING:
    from ..sim.simulator import Simulator

from .encode import Encoder
from .lens import StreamSpec, VideoError, plan_ports, streams_for
from .render import Renderer
from .rtsp import RtspServer, Stream
from .snapshot import SceneState, capture

log = logging.getLogger("topgimbal.video")

DEFAULT_FPS = 30.0
MAX_FPS = 60.0
MAX_BITRATE_KBPS = 100_000
SNAPSHOT_TIMEOUT_S = 1.0
CODEC_POLL_S = 0.2  # how often the codec setting is looked at (a change restarts the stream's encoder)


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
        if self.port is not None and not 0 <= self.port <= 65535:
            raise VideoError(f"port must be 0..65535, 0 for free ports (got {self.port})")
        if self.bitrate_kbps is not None and not 1 <= self.bitrate_kbps <= MAX_BITRATE_KBPS:
            raise VideoError(f"bitrate must be 1..{MAX_BITRATE_KBPS} kbit/s (got {self.bitrate_kbps})")


class SimVideo:
    def __init__(self, sim: Simulator, options: VideoOptions | None = None, **kw: Any) -> None:
        self.sim = sim
        self.options = options or VideoOptions(**kw)
        self.specs = streams_for(sim.model)
        self.servers: list[RtspServer] = []
        self.streams: dict[str, Stream] = {}
        self.urls: dict[str, str] = {}
        self._workers: list[_Worker] = []
        self._loop: asyncio.AbstractEventLoop | None = None
        self._watch: asyncio.Task[None] | None = None
        # The simulator stores only the last encoding write (`stream`, `codec`): each stream's
        # codec is remembered here as writes are seen; a factory reset (new settings) forgets.
        self._ent_codecs: dict[str, str] = {}
        self._ent_seen: tuple[int, Any, Any] | None = None

    def _codec(self, spec: StreamSpec) -> str:
        """The codec a stream should send now: --video-codec, else the model's setting."""
        if self.options.codec:
            return self.options.codec
        settings = self.sim.settings
        ent = settings.get("ENT") or {}
        seen = (id(settings), ent.get("stream"), ent.get("codec"))
        if self._ent_seen is None or seen[0] != self._ent_seen[0]:
            self._ent_codecs.clear()
        if seen != self._ent_seen:
            self._ent_seen = seen
            if ent.get("codec") in ("h264", "h265") and ent.get("stream"):
                self._ent_codecs[str(ent["stream"])] = str(ent["codec"])
        if spec.codec_setting:
            return self._ent_codecs.get(spec.codec_setting, spec.codec)
        return spec.codec

    def _output_started(self) -> None:
        """A receiver plays a stream: the camera's video output has started (a C11 acts on camera
        commands only from then on: the needs_video_output quirk)."""
        self.sim.camera.video_output = True

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
                stream = Stream(
                    spec.path, self._codec(spec), on_keyframe_wanted=worker.want_keyframe, on_play=self._output_started
                )
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
            if any(w.spec.codec_setting for w in self._workers) and not self.options.codec:
                self._watch = asyncio.ensure_future(self._watch_codecs())
        except BaseException:
            await self.stop()
            raise
        return self

    async def _watch_codecs(self) -> None:
        """On the simulator's loop: restart a stream whose codec setting changed."""
        while True:
            await asyncio.sleep(CODEC_POLL_S)
            for w in self._workers:
                stream = w.stream
                if stream is None:
                    continue
                wanted = self._codec(w.spec)
                if wanted != stream.codec:
                    log.info("video %s: codec %s -> %s: restarting the encoder; players reconnect",
                             w.spec.lens, stream.codec, wanted)  # fmt: skip
                    stream.restart(wanted)
                    w.recodec()

    async def stop(self) -> None:
        if self._watch is not None:
            self._watch.cancel()
            with contextlib.suppress(asyncio.CancelledError):
                await self._watch
            self._watch = None
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
        self._recodec = threading.Event()
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

    def recodec(self) -> None:
        """The stream's codec changed: rebuild the encoder before the next picture."""
        self._recodec.set()
        self._key.set()

    def _run(self) -> None:
        assert self.stream is not None
        w, h = self.size
        try:
            renderer = Renderer(self.spec.lens, w, h, self.spec.hfov_deg, mode="YCbCr")
            encoder = Encoder(self.stream.codec, w, h, self.fps, bitrate_kbps=self.video._bitrate())
        except Exception:
            log.exception("video %s: cannot start the encoder", self.spec.lens)
            return
        period = 1.0 / self.fps
        next_t = monotonic()
        try:
            while not self._stop.is_set():
                now = monotonic()
                if now < next_t:
                    self._stop.wait(next_t - now)
                    continue
                if now - next_t > period:
                    # Behind (a busy machine): drop the missed frames instead of bursting them.
                    self.skipped += int((now - next_t) / period)
                    next_t = now
                next_t += period
                if self._recodec.is_set():
                    self._recodec.clear()
                    encoder.close()
                    encoder = Encoder(self.stream.codec, w, h, self.fps, bitrate_kbps=self.video._bitrate())
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
