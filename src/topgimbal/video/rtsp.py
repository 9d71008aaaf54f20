"""A small RTSP server (RFC 2326) for live H.264 / H.265 streams, in asyncio.

Enough of RTSP for ffmpeg/ffprobe, GStreamer, VLC and OpenCV: OPTIONS, DESCRIBE, SETUP (RTP over
the RTSP connection, "interleaved", or over UDP to the client's ports), PLAY, TEARDOWN,
GET_PARAMETER / SET_PARAMETER (keep-alives). Every receiver of a path gets the same encoded
pictures (one encoder per stream, whatever the number of receivers), starting at a keyframe.

Bounds (each refusal is logged; a flood of refused connections in one throttled line per 10 s):
MAX_CONNECTIONS RTSP connections per server (the shared peer table, peers.py), MAX_RECEIVERS
sessions per stream, set up or playing (SETUP beyond it is answered 453), MAX_REQUEST_BYTES per
request, MAX_PIPELINED requests waiting per connection, and MAX_BUFFERED_BYTES unsent per
connection: past it a TCP receiver skips pictures up to the next keyframe instead of queueing, and
requests wait to be answered (a client that reads no answers is closed once MAX_PIPELINED wait).
A session lives as long as its RTSP connection, and a connection from which nothing (no request,
no RTCP) is heard for IDLE_CLOSE_S (the advertised session timeout plus a margin for late
keep-alives) is closed, so abandoned and idle connections give their places back.
"""

from __future__ import annotations

import asyncio
import contextlib
import itertools
import logging

from ..clock import MonotonicFn, monotonic
from ..logthrottle import ThrottledLog
from ..peers import REFUSE, PeerTable, Words
from ..timeouts import within
from .rtsp_connection import MAX_BUFFERED_BYTES, MAX_PIPELINED, SESSION_TIMEOUT_S, SUPPORTED, RtspConnection
from .rtsp_request import Transport, parse_transport, url_path
from .rtsp_stream import KEYFRAME_MIN_INTERVAL_S, Session, Stream

log = logging.getLogger("topgimbal.video.rtsp")

MAX_CONNECTIONS = 16
IDLE_CLOSE_S = SESSION_TIMEOUT_S + 30  # nothing heard this long: the connection is closed
REAP_EVERY_S = 5.0
WORDS = Words(refused="RTSP: refusing {newcomer}: {count} connections already (limit)")


class RtspServer:
    """Serves some streams (by path) on one TCP port."""

    def __init__(self, host: str, port: int, streams: list[Stream], clock: MonotonicFn = monotonic) -> None:
        self.host = host
        self.port = port
        self.streams = {s.path: s for s in streams}
        # The connections, in the shared peer table: refused at MAX_CONNECTIONS, each with the
        # time it was last heard; one unheard for IDLE_CLOSE_S is closed by `reap`.
        self.connections: PeerTable[RtspConnection, RtspConnection] = PeerTable(
            MAX_CONNECTIONS,
            at_cap=REFUSE,
            lease_s=IDLE_CLOSE_S,
            clock=clock,
            name="RTSP",
            throttle=ThrottledLog(log, 10.0),
            words=WORDS,
            describe=lambda c: c.peer,
        )
        self._server: asyncio.base_events.Server | None = None
        self._ids = itertools.count(1)
        self._reaper: asyncio.Task[None] | None = None

    async def start(self) -> RtspServer:
        loop = asyncio.get_running_loop()
        self._server = await loop.create_server(lambda: RtspConnection(self), self.host, self.port)
        self.port = self._server.sockets[0].getsockname()[1]
        self._reaper = loop.create_task(self._reap_forever())
        return self

    def reap(self, now: float | None = None) -> int:
        """Close every connection nothing was heard from for IDLE_CLOSE_S; how many were closed."""
        table = self.connections
        now = table.clock() if now is None else now
        table.lease_s = IDLE_CLOSE_S  # the module's limit, read when it is applied (as it always was)
        closed = 0
        for gone in table.expire(now):
            c = gone.value
            if c.transport is not None and not c.transport.is_closing():
                log.warning(
                    "RTSP %s: nothing heard for %.0f s (no request, no RTCP; the session timeout is %d s): closing",
                    c.peer, now - gone.heard_s, SESSION_TIMEOUT_S,
                )  # fmt: skip
                c.transport.close()
                closed += 1
        return closed

    async def _reap_forever(self) -> None:
        while True:
            await asyncio.sleep(REAP_EVERY_S)
            self.reap()

    @property
    def max_connections(self) -> int:
        return MAX_CONNECTIONS  # this module's limit, read at each connection (a test may lower it)

    def find(self, url: str) -> Stream | None:
        """The stream a request URL names, None for an unknown path; BadUrlError when the URL
        cannot be parsed."""
        path = url_path(url).rstrip("/")
        if path.endswith("/trackID=0"):
            path = path[: -len("/trackID=0")]
        return self.streams.get(path)

    def url(self, path: str) -> str:
        h = f"[{self.host}]" if ":" in self.host else self.host
        return f"rtsp://{h}:{self.port}{path}"

    async def close(self) -> None:
        if self._reaper is not None:
            self._reaper.cancel()
            self._reaper = None
        if self._server is not None:
            self._server.close()
        for c in list(self.connections):
            if c.transport is not None:
                c.transport.close()
        if self._server is not None:
            with contextlib.suppress(Exception):
                await within(self._server.wait_closed(), 2.0)
            self._server = None


__all__ = [
    "IDLE_CLOSE_S",
    "KEYFRAME_MIN_INTERVAL_S",
    "MAX_BUFFERED_BYTES",
    "MAX_PIPELINED",
    "SUPPORTED",
    "RtspServer",
    "Session",
    "Stream",
    "Transport",
    "parse_transport",
]
