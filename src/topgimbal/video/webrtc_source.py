"""One lens's RTSP stream demuxed (not decoded) for the console's WebRTC peers (webrtc.py): a
reader thread per lens, while a peer watches (and IDLE_CLOSE_S after the last one), hands every
access unit, parameter sets put in front of each keyframe that lacks them, to each peer's queue
(QUEUE_PICTURES; a peer that falls behind skips to the next keyframe)."""

from __future__ import annotations

import asyncio
import logging
import threading
from dataclasses import dataclass
from fractions import Fraction
from typing import TYPE_CHECKING, Any

from ..clock import MonotonicFn, monotonic
from .lens import VideoError
from .rtp_push import CODEC_NAMES, OPEN_OPTIONS, ParamSetInserter, is_keyframe

if TYPE_CHECKING:
    import av

log = logging.getLogger("topgimbal.video.webrtc")

IDLE_CLOSE_S = 5.0
RETRY_S = 1.0
READ_TIMEOUT_S = 3.0
QUEUE_PICTURES = 8  # per peer: ~0.25 s at 30 fps; past it the peer skips to the next keyframe
TIME_BASE = Fraction(1, 90000)


@dataclass(eq=False)
class _Peer:
    queue: asyncio.Queue[av.Packet | None]
    loop: asyncio.AbstractEventLoop
    waiting_key: bool = True
    skips: int = 0


class PacketSource:
    """One lens's RTSP stream demuxed (not decoded) for WebRTC peers, read while a peer watches."""

    def __init__(self, name: str, url: str, *, clock: MonotonicFn = monotonic) -> None:
        self.name, self.url, self.clock = name, url, clock
        self.codec: str | None = None
        self.state = "idle"
        self.error: str | None = None
        self.pictures = 0
        self.peers: set[_Peer] = set()
        self._lock = threading.Lock()
        self._thread: threading.Thread | None = None
        self._stop = threading.Event()
        self._last_peer_t = 0.0

    def subscribe(self) -> _Peer:
        peer = _Peer(asyncio.Queue(QUEUE_PICTURES), asyncio.get_running_loop())
        with self._lock:
            self.peers.add(peer)
        self.warm()
        return peer

    def warm(self) -> None:
        """Start reading (if idle) and keep reading IDLE_CLOSE_S even with no peer yet."""
        with self._lock:
            self._last_peer_t = self.clock()
        if self._thread is None or not self._thread.is_alive():
            self._stop.clear()
            self._thread = threading.Thread(target=self._run, name=f"topgimbal-webrtc-{self.name}", daemon=True)
            self._thread.start()

    async def first_picture(self, wait_s: float) -> bool:
        """Whether the stream gives pictures: the first one, or the reader's error, within `wait_s`."""
        end = self.clock() + wait_s
        while self.pictures == 0 and self.clock() < end and not (self.error and self.state == "reconnecting"):
            await asyncio.sleep(0.05)
        return self.pictures > 0

    def unsubscribe(self, peer: _Peer) -> None:
        with self._lock:
            self.peers.discard(peer)
            self._last_peer_t = self.clock()

    def close(self) -> None:
        self._stop.set()

    # -- the reader (thread) -----------------------------------------------------------------------

    def _idle(self) -> bool:
        with self._lock:
            return not self.peers and self.clock() - self._last_peer_t > IDLE_CLOSE_S

    def _run(self) -> None:
        import av

        while not self._stop.is_set() and not self._idle():
            self.state = "connecting" if self.pictures == 0 else "reconnecting"
            try:
                container = av.open(self.url, options={**OPEN_OPTIONS, "rtsp_transport": "tcp"}, timeout=READ_TIMEOUT_S)
            except Exception as exc:  # a camera that does not answer is a state, not a crash
                self._failed(str(exc))
                continue
            try:
                self._pump(container)
                if not self._stop.is_set() and not self._idle():
                    self._failed("the stream ended")
            except Exception as exc:
                self._failed(str(exc))
            finally:
                container.close()
        self.state = "idle"

    def _failed(self, why: str) -> None:
        if self.error != why:
            log.warning("webrtc %s: %s: %s; retrying every %.0f s", self.name, self.url, why, RETRY_S)
        self.error, self.state = why, "reconnecting"
        self._stop.wait(RETRY_S)

    def _pump(self, container: Any) -> None:
        import av

        stream = container.streams.video[0]
        codec = CODEC_NAMES.get(stream.codec_context.name)
        self.codec = codec
        if codec != "h264":
            raise VideoError(f"the stream is {stream.codec_context.name}: browsers take H.264 over WebRTC")
        inserter = ParamSetInserter(codec, stream.codec_context.extradata)
        tb = stream.time_base
        last_pts: int | None = None
        for packet in container.demux(stream):
            if self._stop.is_set() or self._idle():
                return
            data = bytes(packet)
            if not data:
                continue
            nals = inserter.nals(data)
            # FFmpeg gives the first picture it parses no time (docs/errata.md E40): one frame on
            if packet.pts is not None and tb is not None:
                pts = int(packet.pts * tb * 90000)
            else:
                pts = (last_pts + 3000) if last_pts is not None else int(self.clock() * 90000)
            if last_pts is not None and pts <= last_pts:
                pts = last_pts + 1
            last_pts = pts
            out = av.Packet(b"".join(b"\x00\x00\x00\x01" + n for n in nals))
            out.pts, out.time_base = pts, TIME_BASE
            self.state, self.error = "playing", None
            self.pictures += 1
            self._deliver(out, is_keyframe(codec, nals))

    def _deliver(self, packet: av.Packet, key: bool) -> None:
        with self._lock:
            peers = list(self.peers)
        for peer in peers:
            try:
                peer.loop.call_soon_threadsafe(self._offer, peer, packet, key)
            except RuntimeError:  # its loop closed: the console is stopping
                self.unsubscribe(peer)

    def _offer(self, peer: _Peer, packet: av.Packet, key: bool) -> None:
        """On the peer's loop: queue the picture, or skip to the next keyframe when full."""
        if peer.waiting_key and not key:
            return
        peer.waiting_key = False
        try:
            peer.queue.put_nowait(packet)
        except asyncio.QueueFull:
            peer.skips += 1
            if peer.skips == 1 or peer.skips % 100 == 0:
                log.warning("webrtc %s: a peer is %d pictures behind: it skips to the next keyframe (%d times)",
                            self.name, QUEUE_PICTURES, peer.skips)  # fmt: skip
            while not peer.queue.empty():
                peer.queue.get_nowait()
            peer.waiting_key = True
