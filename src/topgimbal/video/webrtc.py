"""WebRTC for the console (aiortc): each lens's H.264 sent to browsers as the camera encoded it,
with a WHEP endpoint per lens (POST an SDP offer -> 201 + the answer and a Location to DELETE).

No decode, no encode: one reader thread per lens demuxes the camera's RTSP stream with PyAV and
hands every access unit (an `av.Packet`, parameter sets put in front of each keyframe that lacks
them) to the peers; aiortc's sender only packetizes pre-encoded packets. A peer starts at a
keyframe (the simulator's GOP: 1 s); a peer that cannot keep up (its queue of QUEUE_PICTURES is
full) drops what is queued and waits for the next keyframe rather than building a backlog.
H.265 is refused (browsers do not take it over WebRTC): the page falls back to MJPEG.

ICE: no STUN or TURN server (nothing leaves the host the browser reached), and the only host
candidate is the address the browser reached the console on (loopback stays loopback).

Bounds, each logged when hit: MAX_PEERS per lens (503 beyond), MAX_OFFER_BYTES per offer, a peer
whose connection fails or that never connects within CONNECT_TIMEOUT_S is closed, a lens's reader
stops IDLE_CLOSE_S after its last peer. An offer is answered only once the camera's stream gave a
picture (FIRST_PICTURE_WAIT_S; else 502 with the reader's error, and the page plays MJPEG).
"""

from __future__ import annotations

import asyncio
import contextvars
import ipaddress
import logging
import secrets
import threading
from dataclasses import dataclass, field
from fractions import Fraction
from typing import TYPE_CHECKING, Any

from ..clock import MonotonicFn, monotonic
from .lens import VideoError
from .rtp_push import CODEC_NAMES, OPEN_OPTIONS, ParamSetInserter, is_keyframe

if TYPE_CHECKING:
    import av

log = logging.getLogger("topgimbal.video.webrtc")

MAX_PEERS = 4  # per lens
MAX_OFFER_BYTES = 64 * 1024
CONNECT_TIMEOUT_S = 15.0
FIRST_PICTURE_WAIT_S = 5.0  # a WHEP offer waits this long for the camera's stream before a 502
IDLE_CLOSE_S = 5.0
RETRY_S = 1.0
READ_TIMEOUT_S = 3.0
QUEUE_PICTURES = 8  # per peer: ~0.25 s at 30 fps; past it the peer skips to the next keyframe
TIME_BASE = Fraction(1, 90000)

# The host address ICE may use for the peer being set up (the console's side of the browser's
# HTTP connection): aioice reads it when it gathers candidates (see _patch_aioice).
_ice_host: contextvars.ContextVar[str | None] = contextvars.ContextVar("topgimbal_ice_host", default=None)


def _patch_aioice() -> None:
    """aioice gathers every interface's address but loopback's; the console offers exactly the
    address the browser reached it on instead (only while a WHEP answer is made, by context)."""
    import aioice.ice as ice

    if getattr(ice, "_topgimbal_patched", False):
        return
    original = ice.get_host_addresses

    def host_addresses(use_ipv4: bool, use_ipv6: bool) -> list[str]:
        host = _ice_host.get()
        return [host] if host else original(use_ipv4, use_ipv6)

    ice.get_host_addresses = host_addresses
    ice._topgimbal_patched = True  # type: ignore[attr-defined]


def _is_loopback(address: str) -> bool:
    try:
        return ipaddress.ip_address(address.strip("[]")).is_loopback
    except ValueError:
        return address == "localhost"


def remote_candidates(offer_sdp: str, host: str | None) -> str:
    """The offer with only the browser's candidates the console may send to. A console reached on
    loopback checks only loopback candidates: a browser also lists its other interfaces and mDNS
    names (`x.local`, which aioice would resolve with a multicast query), and a loopback console
    must put nothing on any other address, not even this computer's own."""
    if host is None or not _is_loopback(host):
        return offer_sdp
    kept = []
    for line in offer_sdp.splitlines():
        if line.startswith("a=candidate:"):
            parts = line.split()
            if len(parts) < 5 or not _is_loopback(parts[4]):
                continue
        kept.append(line)
    return "\r\n".join(kept) + "\r\n"


class WebRtcError(VideoError):
    """A WHEP request that cannot be served (the status says why)."""

    def __init__(self, status: int, message: str) -> None:
        super().__init__(message)
        self.status = status


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


def _track_class() -> type:
    from aiortc import MediaStreamTrack

    class PassthroughTrack(MediaStreamTrack):  # type: ignore[misc]
        """A video track whose `recv()` gives pre-encoded H.264 (aiortc's sender packs it)."""

        kind = "video"

        def __init__(self, source: PacketSource) -> None:
            super().__init__()
            self.source = source
            self.peer = source.subscribe()

        async def recv(self) -> av.Packet:
            packet = await self.peer.queue.get()
            if packet is None:
                raise ConnectionError("the stream closed")
            return packet

        def stop(self) -> None:
            self.source.unsubscribe(self.peer)
            super().stop()

    return PassthroughTrack


@dataclass
class _Session:
    id: str
    lens: str
    pc: Any
    track: Any
    created_t: float
    watchdog: asyncio.Task[None] | None = field(default=None, repr=False)


class WhepServer:
    """The WHEP sessions of one console: per lens a PacketSource and at most MAX_PEERS peers."""

    def __init__(self, urls: dict[str, str], *, clock: MonotonicFn = monotonic) -> None:
        self.sources = {lens: PacketSource(lens, url, clock=clock) for lens, url in urls.items()}
        self.sessions: dict[str, _Session] = {}
        self.clock = clock

    def peers(self, lens: str) -> int:
        return sum(1 for s in self.sessions.values() if s.lens == lens)

    async def answer(self, lens: str, offer_sdp: str, host: str | None) -> tuple[str, str]:
        """(session id, answer SDP) for a browser's offer. Raises WebRtcError."""
        try:
            from aiortc import RTCConfiguration, RTCPeerConnection, RTCRtpSender, RTCSessionDescription
        except ImportError as exc:
            raise WebRtcError(501, f"WebRTC needs the webrtc extra (pip install 'topgimbal[webrtc]'): {exc}") from None
        source = self.sources.get(lens)
        if source is None:
            raise WebRtcError(404, f"no such lens; this camera has: {', '.join(self.sources)}")
        if source.codec not in (None, "h264"):
            raise WebRtcError(415, f"the {lens} stream is {source.codec}: browsers take only H.264 over WebRTC "
                                   f"(use /video/{lens}.mjpg)")  # fmt: skip
        if self.peers(lens) >= MAX_PEERS:
            log.warning("webrtc %s: refusing a peer: %d already (the limit)", lens, MAX_PEERS)
            raise WebRtcError(503, f"{MAX_PEERS} WebRTC peers already play the {lens} stream")
        if "m=video" not in offer_sdp:
            raise WebRtcError(400, "the offer has no video section (m=video)")
        _patch_aioice()
        track = _track_class()(source)
        # Answer only once the camera's stream is there (never a session for a stream that is
        # not): the first picture, or the reader's error, within FIRST_PICTURE_WAIT_S.
        if not await source.first_picture(FIRST_PICTURE_WAIT_S) or source.codec != "h264":
            track.stop()
            if source.codec not in (None, "h264"):
                raise WebRtcError(415, f"the {lens} stream is {source.codec}: browsers take only H.264 over WebRTC "
                                       f"(use /video/{lens}.mjpg)")  # fmt: skip
            raise WebRtcError(502, f"no picture from the {lens} stream ({source.error or 'nothing came'})")
        pc = RTCPeerConnection(RTCConfiguration(iceServers=[]))
        token = _ice_host.set(host)
        try:
            # H.264 only (and its retransmissions): the packets are the camera's, nothing re-encodes
            # them. The transceiver exists before the offer so its preferences shape the answer.
            caps = RTCRtpSender.getCapabilities("video").codecs
            keep = [c for c in caps if c.mimeType.lower() in ("video/h264", "video/rtx")]
            pc.addTransceiver(track, direction="sendonly").setCodecPreferences(keep)
            await pc.setRemoteDescription(RTCSessionDescription(remote_candidates(offer_sdp, host), "offer"))
            await pc.setLocalDescription(await pc.createAnswer())
        except WebRtcError:
            track.stop()
            await pc.close()
            raise
        except Exception as exc:  # a malformed or unmatchable offer is the client's error
            track.stop()
            await pc.close()
            raise WebRtcError(400, f"cannot answer this offer: {exc}") from None
        finally:
            _ice_host.reset(token)
        answer = pc.localDescription.sdp
        if "H264" not in answer.upper():
            track.stop()
            await pc.close()
            raise WebRtcError(406, "the browser offered no H.264: use the MJPEG stream")
        sid = secrets.token_urlsafe(12)
        session = _Session(sid, lens, pc, track, self.clock())
        self.sessions[sid] = session

        @pc.on("connectionstatechange")  # type: ignore[misc]
        async def on_state() -> None:
            if pc.connectionState in ("failed", "closed"):
                await self.end(sid, why=f"connection {pc.connectionState}")

        session.watchdog = asyncio.ensure_future(self._watch(sid))
        log.info("webrtc %s: peer %s (%d of %d)", lens, sid, self.peers(lens), MAX_PEERS)
        return sid, answer

    async def ready(self, lens: str) -> dict[str, Any]:
        """Whether a lens can play over WebRTC now (the page asks before it offers): its reader
        started, the first picture or the error awaited (FIRST_PICTURE_WAIT_S)."""
        source = self.sources.get(lens)
        if source is None:
            raise WebRtcError(404, f"no such lens; this camera has: {', '.join(self.sources)}")
        source.warm()
        ok = await source.first_picture(FIRST_PICTURE_WAIT_S)
        why = None if ok else source.error or "nothing came"
        if ok and source.codec != "h264":
            ok, why = False, f"the stream is {source.codec}: browsers take only H.264 over WebRTC"
        if ok and self.peers(lens) >= MAX_PEERS:
            ok, why = False, f"{MAX_PEERS} WebRTC peers already play it"
        return {"ready": ok, "codec": source.codec, "why": why}

    async def _watch(self, sid: str) -> None:
        await asyncio.sleep(CONNECT_TIMEOUT_S)
        s = self.sessions.get(sid)
        if s is not None and s.pc.connectionState != "connected":
            await self.end(sid, why=f"not connected within {CONNECT_TIMEOUT_S:.0f} s")

    async def end(self, sid: str, why: str = "ended") -> bool:
        s = self.sessions.pop(sid, None)
        if s is None:
            return False
        log.info("webrtc %s: peer %s %s", s.lens, sid, why)
        s.track.stop()
        if s.watchdog is not None and s.watchdog is not asyncio.current_task():
            s.watchdog.cancel()
        await s.pc.close()
        return True

    async def close(self) -> None:
        for sid in list(self.sessions):
            await self.end(sid, why="the console is stopping")
        for source in self.sources.values():
            source.close()

    def status(self, lens: str) -> dict[str, Any]:
        """What the page shows for a lens it plays over WebRTC (the reader's state, as the relay's)."""
        src = self.sources.get(lens)
        if src is None:
            return {"peers": 0, "max_peers": MAX_PEERS, "codec": None}
        return {"peers": self.peers(lens), "max_peers": MAX_PEERS, "codec": src.codec, "state": src.state,
                "error": src.error, "pictures": src.pictures}  # fmt: skip


def available() -> bool:
    try:
        import aiortc  # noqa: F401
    except ImportError:
        return False
    return True
