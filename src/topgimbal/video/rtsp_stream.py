"""One live RTSP stream (a path) and the sessions set up on it: the encoded pictures go to every
playing session as RTP, interleaved on its RTSP connection or over UDP, starting at a keyframe.

Every receiver shares the stream's one encoder, so a keyframe forced for one receiver reaches all
of them (a keyframe is ~10x the size of another picture). Forced keyframes are therefore rate
limited per stream: the encoder is asked for one only when no keyframe (forced or its own, every
GOP) went out in the last KEYFRAME_MIN_INTERVAL_S; a wish made sooner is kept and asked for at the
first picture after the interval, unless a keyframe came meanwhile. A client that floods PLAY (or
SETUP/PLAY/TEARDOWN cycles) thus adds at most one keyframe per interval to what the others get."""

from __future__ import annotations

import asyncio
import logging
import struct
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Protocol

from ..clock import monotonic
from ..logthrottle import ThrottledLog
from .encode import AccessUnit
from .rtp import CLOCK_HZ, Packetizer, parameter_sets, split_nals

log = logging.getLogger("topgimbal.video.rtsp")
_FRAME_HEAD = struct.Struct("!cBH")
# At most one forced keyframe per this many seconds per stream (the simulator's GOP is 1 s, so a
# new receiver waits at most ~1 s for its first picture; see docs/video.md).
KEYFRAME_MIN_INTERVAL_S = 1.0


class Connection(Protocol):
    """What a session needs of its RTSP connection."""

    transport: asyncio.Transport | None
    peer: str


class Stream:
    """One live stream (one path): the latest parameter sets and the receivers playing it."""

    def __init__(
        self,
        path: str,
        codec: str,
        *,
        on_keyframe_wanted: Callable[[], None] | None = None,
        on_play: Callable[[], None] | None = None,
        clock: Callable[[], float] = monotonic,
    ) -> None:
        self.path = path
        self.codec = codec
        self.generation = 0  # encoder restarts so far: an SDP describes one generation's codec
        self.params: dict[str, bytes] = {}
        self.ready = asyncio.Event()
        self.receivers: set[Session] = set()  # playing
        self.sessions: set[Session] = set()  # set up, playing or not: what MAX_RECEIVERS bounds
        self.pictures = 0
        self._want_key = on_keyframe_wanted or (lambda: None)
        self.on_play = on_play or (lambda: None)
        self.clock = clock
        self.keyframes_asked = 0  # forced keyframes asked of the encoder
        self.keyframes_deferred = 0  # wishes that had to wait for KEYFRAME_MIN_INTERVAL_S
        self._key_wanted = False
        self._last_key_t: float | None = None  # the last keyframe published or asked for
        self._deferred_log = ThrottledLog(log, 60.0, lambda: self.clock())  # info, once a minute

    def publish(self, au: AccessUnit) -> None:
        """Send one access unit to every receiver (on the server's event loop)."""
        if au.codec != self.codec:
            return  # encoded before a codec change, delivered after it
        self.pictures += 1
        if au.keyframe:
            self._key_wanted = False
            self._last_key_t = self.clock()
            found = parameter_sets(self.codec, split_nals(au.data))
            if found:
                self.params.update(found)
                self.ready.set()
        elif self._key_wanted:
            self._ask_keyframe()
        rtp_time = int(au.pts_s * CLOCK_HZ) & 0xFFFFFFFF
        for r in list(self.receivers):
            try:
                r.send_picture(au, rtp_time)
            except Exception:  # one broken receiver must not starve the others
                log.exception("RTSP %s: sending to %s failed: dropping that receiver", self.path, r.conn.peer)
                r.close()

    def want_keyframe(self) -> None:
        """A new receiver (or a DESCRIBE) wants a keyframe: asked of the encoder now if none went
        out in the last KEYFRAME_MIN_INTERVAL_S, else at the first picture after it."""
        self._key_wanted = True
        self._ask_keyframe()

    def _ask_keyframe(self) -> None:
        now = self.clock()
        last = self._last_key_t
        if last is not None and now - last < KEYFRAME_MIN_INTERVAL_S:
            self.keyframes_deferred += 1
            if self._deferred_log.allow("deferred") is not None:
                log.info("RTSP %s: keyframes wanted faster than one per %g s: the wish waits (%d deferred in all)",
                         self.path, KEYFRAME_MIN_INTERVAL_S, self.keyframes_deferred)  # fmt: skip
            return
        self._key_wanted = False
        self._last_key_t = now
        self.keyframes_asked += 1
        self._want_key()

    def restart(self, codec: str) -> None:
        """The encoder restarts with another codec: forget the parameter sets (DESCRIBE waits
        for the new ones) and disconnect every player (an RTP session cannot change its payload
        format; players that reconnect get the new SDP)."""
        self.codec = codec
        self.generation += 1
        self.params = {}
        self.ready.clear()
        self._last_key_t = None  # the new encoder starts with a keyframe of its own
        for r in list(self.sessions):
            log.info("RTSP %s: codec now %s: disconnecting %s", self.path, codec, r.conn.peer)
            r.close()
            if r.conn.transport is not None:
                r.conn.transport.close()

    def now_rtp(self) -> int:
        return int(monotonic() * CLOCK_HZ) & 0xFFFFFFFF


@dataclass(eq=False)  # identity: a set member
class Session:
    id: str
    stream: Stream
    conn: Connection
    packetizer: Packetizer
    channel: int | None = None  # interleaved RTP channel (TCP)
    udp: asyncio.DatagramTransport | None = None
    udp_rtcp: asyncio.DatagramTransport | None = None
    udp_peer: tuple[str, int] | None = None
    playing: bool = False
    waiting_key: bool = True
    dropped: int = 0
    server_ports: tuple[int, int] = (0, 0)
    _congested: bool = field(default=False, repr=False)

    def send_picture(self, au: AccessUnit, rtp_time: int) -> None:
        if not self.playing:
            return
        if self.waiting_key:
            if not au.keyframe:
                return
            self.waiting_key = False
        if self.channel is not None:
            tr = self.conn.transport
            if tr is None or tr.is_closing():
                return
            if tr.get_write_buffer_size() > tr.get_write_buffer_limits()[1]:  # the connection's high-water mark
                # A receiver that cannot keep up skips to the next keyframe rather than queue.
                self.dropped += 1
                self.waiting_key = True
                if not self._congested:
                    log.warning(
                        "RTSP %s: receiver %s too slow, skipping to the next keyframe", self.stream.path, self.conn.peer
                    )
                    self._congested = True
                return
            self._congested = False
            tr.writelines(
                [_FRAME_HEAD.pack(b"$", self.channel, len(p)) + p for p in self.packetizer.packets(au.data, rtp_time)]
            )
        elif self.udp is not None and self.udp_peer is not None:
            for p in self.packetizer.packets(au.data, rtp_time):
                self.udp.sendto(p, self.udp_peer)

    def close(self) -> None:
        self.playing = False
        self.stream.receivers.discard(self)
        self.stream.sessions.discard(self)
        for t in (self.udp, self.udp_rtcp):
            if t is not None:
                t.close()
        self.udp = self.udp_rtcp = None
