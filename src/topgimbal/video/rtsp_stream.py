"""One live RTSP stream (a path) and the sessions set up on it: the encoded pictures go to every
playing session as RTP, interleaved on its RTSP connection or over UDP, starting at a keyframe."""

from __future__ import annotations

import asyncio
import logging
import struct
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Protocol

from .encode import AccessUnit
from .rtp import CLOCK_HZ, Packetizer, parameter_sets, split_nals

log = logging.getLogger("topgimbal.video.rtsp")
_FRAME_HEAD = struct.Struct("!cBH")


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
    ) -> None:
        self.path = path
        self.codec = codec
        self.params: dict[str, bytes] = {}
        self.ready = asyncio.Event()
        self.receivers: set[Session] = set()  # playing
        self.sessions: set[Session] = set()  # set up, playing or not: what MAX_RECEIVERS bounds
        self.pictures = 0
        self._want_key = on_keyframe_wanted or (lambda: None)
        self.on_play = on_play or (lambda: None)

    def publish(self, au: AccessUnit) -> None:
        """Send one access unit to every receiver (on the server's event loop)."""
        if au.codec != self.codec:
            return  # encoded before a codec change, delivered after it
        self.pictures += 1
        if au.keyframe:
            found = parameter_sets(self.codec, split_nals(au.data))
            if found:
                self.params.update(found)
                self.ready.set()
        rtp_time = int(au.pts_s * CLOCK_HZ) & 0xFFFFFFFF
        for r in list(self.receivers):
            try:
                r.send_picture(au, rtp_time)
            except Exception:  # one broken receiver must not starve the others
                log.exception("RTSP %s: sending to %s failed: dropping that receiver", self.path, r.conn.peer)
                r.close()

    def want_keyframe(self) -> None:
        self._want_key()

    def restart(self, codec: str) -> None:
        """The encoder restarts with another codec: forget the parameter sets (DESCRIBE waits
        for the new ones) and disconnect every player (an RTP session cannot change its payload
        format; players that reconnect get the new SDP)."""
        self.codec = codec
        self.params = {}
        self.ready.clear()
        for r in list(self.sessions):
            log.info("RTSP %s: codec now %s: disconnecting %s", self.path, codec, r.conn.peer)
            r.close()
            if r.conn.transport is not None:
                r.conn.transport.close()

    def now_rtp(self) -> int:
        return int(time.monotonic() * CLOCK_HZ) & 0xFFFFFFFF


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
