"""WebRTC for the console (aiortc): each lens's H.264 sent to browsers as the camera encoded it,
with a WHEP endpoint per lens (POST an SDP offer -> 201 + the answer and a Location to DELETE).

No decode, no encode: one reader thread per lens demuxes the camera's RTSP stream with PyAV and
hands every access unit (an `av.Packet`, parameter sets put in front of each keyframe that lacks
them) to the peers; aiortc's sender only packetizes pre-encoded packets. A peer starts at a
keyframe (the simulator's GOP: 1 s); a peer that cannot keep up (its queue of QUEUE_PICTURES is
full) drops what is queued and waits for the next keyframe rather than building a backlog.
H.265 is refused (browsers do not take it over WebRTC): the page falls back to MJPEG.

ICE: no STUN or TURN server (nothing leaves the host the browser reached), the only host candidate
is the address the browser reached the console on (loopback stays loopback), and of the browser's
candidates only those on that address's network are kept (ice_candidates.py).

Bounds, each logged when hit: MAX_PEERS per lens (503 beyond; a place is taken when the offer is
checked, before any wait, so concurrent offers cannot pass the check together; the last place is
kept for the console's own page), MAX_CONNECTING peers per lens not yet connected (a further offer
replaces the oldest of them: offers that never finish ICE cannot hold the places),
MAX_OFFER_BYTES per offer, a peer whose connection fails or that never connects within
CONNECT_TIMEOUT_S is closed, a lens's reader
stops IDLE_CLOSE_S after its last peer. An offer is answered only once the camera's stream gave a
picture (FIRST_PICTURE_WAIT_S; else 502 with the reader's error, and the page plays MJPEG).
"""

from __future__ import annotations

import asyncio
import contextvars
import logging
import secrets
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any

from ..clock import MonotonicFn, monotonic
from ..logthrottle import ThrottledLog
from .ice_candidates import remote_candidates
from .lens import VideoError
from .webrtc_source import PacketSource

if TYPE_CHECKING:
    import av

log = logging.getLogger("topgimbal.video.webrtc")

MAX_PEERS = 4  # per lens
REFUSAL_LOG_EVERY_S = 10.0
MAX_CONNECTING = 2  # per lens: peers answered that have not connected yet (the oldest replaced beyond)
MAX_OFFER_BYTES = 64 * 1024
CONNECT_TIMEOUT_S = 15.0
FIRST_PICTURE_WAIT_S = 5.0  # a WHEP offer waits this long for the camera's stream before a 502

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


class WebRtcError(VideoError):
    """A WHEP request that cannot be served (the status says why)."""

    def __init__(self, status: int, message: str) -> None:
        super().__init__(message)
        self.status = status


def _track_class() -> type:
    from aiortc import MediaStreamTrack

    class PassthroughTrack(MediaStreamTrack):
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


def _connected(s: _Session) -> bool:
    return getattr(s.pc, "connectionState", "connected") == "connected"  # no pc: a test's placeholder


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
        self._answering: dict[str, int] = {}  # offers being answered per lens: their places are taken
        self._refusals = ThrottledLog(log, REFUSAL_LOG_EVERY_S)  # a flood of offers: one line per interval

    def peers(self, lens: str) -> int:
        """Places taken on a lens: its sessions and the offers being answered."""
        return sum(1 for s in self.sessions.values() if s.lens == lens) + self._answering.get(lens, 0)

    def _take_place(self, lens: str, page: bool) -> _Session | None:
        """Takes a place for an offer (no await: concurrent offers see each other) and returns the
        session it replaces: the oldest not yet connected when MAX_CONNECTING are (they hold no
        place for ever). The last place is the page's. Raises WebRtcError 503."""
        waiting = sorted((s for s in self.sessions.values() if s.lens == lens and not _connected(s)),
                         key=lambda s: s.created_t)  # fmt: skip
        victim = None
        if len(waiting) + self._answering.get(lens, 0) >= MAX_CONNECTING:
            if not waiting:
                self._refusals.warning(
                    "answering", "webrtc %s: refusing a peer: %d offers are being answered (the limit)", lens,
                    MAX_CONNECTING,
                )  # fmt: skip
                raise WebRtcError(503, f"{MAX_CONNECTING} WebRTC offers for the {lens} stream are being answered")
            victim = self.sessions.pop(waiting[0].id)
        limit = MAX_PEERS if page else MAX_PEERS - 1
        if self.peers(lens) >= limit:
            if victim is not None:
                self.sessions[victim.id] = victim
            self._refusals.warning("full", "webrtc %s: refusing a peer: %d already (the limit%s)", lens,
                                   self.peers(lens), "" if page else "; the last place is kept for the console's page")  # fmt: skip
            raise WebRtcError(503, f"{self.peers(lens)} WebRTC peers already play the {lens} stream")
        self._answering[lens] = self._answering.get(lens, 0) + 1
        return victim

    async def answer(self, lens: str, offer_sdp: str, host: str | None, *, page: bool = True) -> tuple[str, str]:
        """(session id, answer SDP) for a browser's offer (`page`: from the console's own page, which
        may take the last place). Raises WebRtcError."""
        try:
            import aiortc  # noqa: F401
        except ImportError as exc:
            raise WebRtcError(501, f"WebRTC needs the webrtc extra (pip install 'topgimbal[webrtc]'): {exc}") from None
        source = self.sources.get(lens)
        if source is None:
            raise WebRtcError(404, f"no such lens; this camera has: {', '.join(self.sources)}")
        if source.codec not in (None, "h264"):
            raise WebRtcError(415, f"the {lens} stream is {source.codec}: browsers take only H.264 over WebRTC "
                                   f"(use /video/{lens}.mjpg)")  # fmt: skip
        if "m=video" not in offer_sdp:
            raise WebRtcError(400, "the offer has no video section (m=video)")
        victim = self._take_place(lens, page)
        try:
            if victim is not None:
                await self._close(victim, f"replaced: not connected while {MAX_CONNECTING} newer offers waited")
            return await self._answer(source, lens, offer_sdp, host)
        finally:
            self._answering[lens] -= 1

    async def _answer(self, source: PacketSource, lens: str, offer_sdp: str, host: str | None) -> tuple[str, str]:
        from aiortc import RTCConfiguration, RTCPeerConnection, RTCRtpSender, RTCSessionDescription

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

        @pc.on("connectionstatechange")
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
        await self._close(s, why)
        return True

    async def _close(self, s: _Session, why: str) -> None:
        sid = s.id
        log.info("webrtc %s: peer %s %s", s.lens, sid, why)
        s.track.stop()
        if s.watchdog is not None and s.watchdog is not asyncio.current_task():
            s.watchdog.cancel()
        await s.pc.close()

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
