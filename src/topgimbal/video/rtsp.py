"""A small RTSP server (RFC 2326) for live H.264 / H.265 streams, in asyncio.

Enough of RTSP for ffmpeg/ffprobe, GStreamer, VLC and OpenCV: OPTIONS, DESCRIBE, SETUP (RTP over
the RTSP connection, "interleaved", or over UDP to the client's ports), PLAY, TEARDOWN,
GET_PARAMETER / SET_PARAMETER (keep-alives). Every receiver of a path gets the same encoded
pictures (one encoder per stream, whatever the number of receivers), starting at a keyframe.

Bounds (each refusal is logged): MAX_CONNECTIONS RTSP connections per server, MAX_RECEIVERS
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
import random
import struct
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any
from urllib.parse import urlsplit

from .encode import AccessUnit
from .rtp import CLOCK_HZ, Packetizer, parameter_sets, sdp, split_nals

log = logging.getLogger("topgimbal.video.rtsp")

MAX_CONNECTIONS = 16
MAX_RECEIVERS = 8
MAX_REQUEST_BYTES = 8192
MAX_PIPELINED = 32  # requests waiting for an answer on one connection
MAX_BUFFERED_BYTES = 2_000_000
DESCRIBE_WAIT_S = 5.0
SESSION_TIMEOUT_S = 60  # advertised in SETUP's Session header: clients keep alive within it
IDLE_CLOSE_S = SESSION_TIMEOUT_S + 30  # nothing heard this long: the connection is closed
REAP_EVERY_S = 5.0
SERVER_NAME = "topgimbal-sim"
SUPPORTED = ("OPTIONS", "DESCRIBE", "SETUP", "PLAY", "TEARDOWN", "GET_PARAMETER", "SET_PARAMETER")
# RTSP methods this server knows but does not offer (405 with Allow); anything else is 501.
NOT_ALLOWED = ("ANNOUNCE", "PAUSE", "RECORD", "REDIRECT", "PLAY_NOTIFY")
MAX_CHANNEL = 254  # interleaved RTP channel; RTCP takes the next one, and both must fit in a byte
_FRAME_HEAD = struct.Struct("!cBH")


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
        self.receivers: set[_Session] = set()  # playing
        self.sessions: set[_Session] = set()  # set up, playing or not: what MAX_RECEIVERS bounds
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
class _Session:
    id: str
    stream: Stream
    conn: _Connection
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
            if tr.get_write_buffer_size() > MAX_BUFFERED_BYTES:
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


class _Heard(asyncio.DatagramProtocol):
    """RTCP receiver reports and NAT probes arrive here: they only show the receiver is alive."""

    def __init__(self, conn: _Connection) -> None:
        self.conn = conn

    def datagram_received(self, data: bytes, addr: tuple[str | Any, int]) -> None:
        self.conn.heard()


@dataclass(frozen=True)
class Transport:
    """What a SETUP's Transport header asks for, once understood: RTP over the RTSP connection
    (`tcp`, channels `rtp`/`rtcp`) or over UDP to the client's ports `rtp`/`rtcp`."""

    tcp: bool
    rtp: int
    rtcp: int

    def header(self) -> str:
        if self.tcp:
            return f"RTP/AVP/TCP;unicast;interleaved={self.rtp}-{self.rtcp}"
        return f"RTP/AVP;unicast;client_port={self.rtp}-{self.rtcp}"


def parse_transport(header: str, busy_channels: set[int] | frozenset[int] = frozenset()) -> Transport | None:
    """The first alternative of a Transport header (RFC 2326 12.39: comma-separated, in the
    client's order of preference) this server can serve: unicast RTP/AVP over TCP with
    interleaved channels 0..255 (the lowest free pair when not given), or over UDP with client
    ports 1..65535. None when there is none (the answer is 461)."""
    for alternative in header.split(","):
        opts = [o.strip() for o in alternative.split(";") if o.strip()]
        if not opts:
            continue
        profile = opts[0].upper()
        params: dict[str, str] = {}
        for o in opts[1:]:
            k, _, v = o.partition("=")
            params[k.strip().lower()] = v.strip()
        if profile not in ("RTP/AVP", "RTP/AVP/UDP", "RTP/AVP/TCP") or "multicast" in params:
            continue
        if profile == "RTP/AVP/TCP":
            if "interleaved" in params:
                pair = _number_pair(params["interleaved"], 0, 255)
            else:
                free = next(
                    (c for c in range(0, 255, 2) if c not in busy_channels and c + 1 not in busy_channels), None
                )
                pair = None if free is None else (free, free + 1)
            if pair is not None:
                return Transport(True, *pair)
        elif "client_port" in params:
            pair = _number_pair(params["client_port"], 1, 65535)
            if pair is not None:
                return Transport(False, *pair)
    return None


def _number_pair(text: str, lo: int, hi: int) -> tuple[int, int] | None:
    """N or N-M (digits) with both within lo..hi ("N" alone means N and N+1), else None."""
    first, sep, second = text.partition("-")
    if not sep:
        second = str(int(first) + 1) if first.isascii() and first.isdigit() and len(first) <= 5 else ""
    if not all(t.isascii() and t.isdigit() and len(t) <= 5 for t in (first, second)):
        return None
    a, b = int(first), int(second)
    return (a, b) if lo <= a <= hi and lo <= b <= hi else None


@dataclass
class _Request:
    method: str
    url: str
    headers: dict[str, str]
    version: str = "RTSP/1.0"


class _Connection(asyncio.Protocol):
    def __init__(self, server: RtspServer) -> None:
        self.server = server
        self.transport: asyncio.Transport | None = None
        self.peer: str = "?"
        self.buf = b""
        self.sessions: dict[str, _Session] = {}
        self.queue: asyncio.Queue[_Request] = asyncio.Queue()
        self.task: asyncio.Task[None] | None = None
        self.last_heard = time.monotonic()
        # Set while the transport's unsent bytes are under its high-water mark (MAX_BUFFERED_BYTES):
        # requests wait for it, so a client that sends requests but reads no answers makes its
        # requests pile up (and is closed past MAX_PIPELINED) instead of the answers growing
        # without bound in memory.
        self.writable = asyncio.Event()
        self.writable.set()

    def pause_writing(self) -> None:
        self.writable.clear()

    def resume_writing(self) -> None:
        self.writable.set()

    def heard(self) -> None:
        """The client showed it is alive: a request, interleaved RTCP, or RTCP over UDP."""
        self.last_heard = time.monotonic()

    def connection_made(self, transport: asyncio.BaseTransport) -> None:
        self.transport = transport  # type: ignore[assignment]
        peer = transport.get_extra_info("peername")
        self.peer = f"{peer[0]}:{peer[1]}" if peer else "?"
        if len(self.server.connections) >= MAX_CONNECTIONS:
            log.warning("RTSP: refusing %s: %d connections already (limit)", self.peer, MAX_CONNECTIONS)
            transport.close()
            return
        self.server.connections.add(self)
        if self.transport is not None:
            self.transport.set_write_buffer_limits(high=MAX_BUFFERED_BYTES, low=MAX_BUFFERED_BYTES // 2)
        self.task = asyncio.get_running_loop().create_task(self._serve())

    def connection_lost(self, exc: Exception | None) -> None:
        self.server.connections.discard(self)
        for s in self.sessions.values():
            s.close()
        self.sessions.clear()
        if self.task is not None:
            self.task.cancel()

    def data_received(self, data: bytes) -> None:
        self.heard()
        self.buf += data
        while self.buf:
            if self.buf[:1] == b"$":  # interleaved RTCP from the receiver: skip it
                if len(self.buf) < 4:
                    return
                n = int.from_bytes(self.buf[2:4], "big")
                if len(self.buf) < 4 + n:
                    return
                self.buf = self.buf[4 + n :]
                continue
            end = self.buf.find(b"\r\n\r\n")
            if end < 0:
                if len(self.buf) > MAX_REQUEST_BYTES:
                    self._bad("request header too long")
                return
            head = self.buf[:end].decode("utf-8", "replace")
            lines = head.split("\r\n")
            headers: dict[str, str] = {}
            for line in lines[1:]:
                k, sep, v = line.partition(":")
                if sep:
                    headers[k.strip().lower()] = v.strip()
            try:
                body_len = int(headers.get("content-length", "0"))
            except ValueError:
                body_len = -1
            if not 0 <= body_len <= MAX_REQUEST_BYTES:
                self._bad("bad Content-Length")
                return
            if len(self.buf) < end + 4 + body_len:
                return
            self.buf = self.buf[end + 4 + body_len :]
            parts = lines[0].split()
            if len(parts) != 3 or not parts[2].startswith("RTSP/"):
                self._bad(f"not an RTSP request line: {lines[0][:80]!r}")
                return
            if self.queue.qsize() >= MAX_PIPELINED:
                self._bad(f"more than {MAX_PIPELINED} requests waiting (answers unread: {self._unsent()} bytes)")
                return
            self.queue.put_nowait(_Request(parts[0].upper(), parts[1], headers, parts[2]))

    def _unsent(self) -> int:
        return self.transport.get_write_buffer_size() if self.transport is not None else 0

    def _bad(self, why: str) -> None:
        log.warning("RTSP %s: %s; closing", self.peer, why)
        self.reply(_Request("?", "", {}), 400, "Bad Request")
        self.buf = b""
        if self.transport is not None:
            self.transport.close()

    def reply(
        self, req: _Request, code: int, reason: str, headers: dict[str, str] | None = None, body: str = ""
    ) -> None:
        if self.transport is None or self.transport.is_closing():
            return
        lines = [f"RTSP/1.0 {code} {reason}"]
        if _cseq_ok(req):
            lines.append(f"CSeq: {req.headers['cseq']}")
        lines.append(f"Server: {SERVER_NAME}")
        lines += [f"{k}: {v}" for k, v in (headers or {}).items()]
        data = body.encode()
        if data:
            lines.append(f"Content-Length: {len(data)}")
        self.transport.write(("\r\n".join(lines) + "\r\n\r\n").encode() + data)

    async def _serve(self) -> None:
        while True:
            req = await self.queue.get()
            await self.writable.wait()
            try:
                await self._handle(req)
            except Exception:  # a bad request must not take the server down
                log.exception("RTSP %s: %s failed", self.peer, req.method)
                self.reply(req, 500, "Internal Server Error")

    # -- methods ----------------------------------------------------------------------------------

    async def _handle(self, req: _Request) -> None:
        m = req.method
        # RFC 2326 12.17: every request carries CSeq; RFC 7826 7.1.1: a version the server does
        # not speak is 505. Both answers keep the connection (the request itself was framed).
        if not _cseq_ok(req):
            log.warning("RTSP %s: %s without a numeric CSeq: 400", self.peer, m[:20])
            self.reply(req, 400, "Bad Request")
            return
        if req.version != "RTSP/1.0":
            log.warning("RTSP %s: %s in %s: 505", self.peer, m[:20], req.version[:20])
            self.reply(req, 505, "RTSP Version Not Supported")
            return
        if m == "OPTIONS":
            self.reply(req, 200, "OK", {"Public": ", ".join(SUPPORTED)})
        elif m == "DESCRIBE":
            await self._describe(req)
        elif m == "SETUP":
            await self._setup(req)
        elif m == "PLAY":
            self._play(req)
        elif m == "TEARDOWN":
            s = self._session(req)
            if s is None:
                self.reply(req, 454, "Session Not Found")
                return
            s.close()
            self.sessions.pop(s.id, None)
            self.reply(req, 200, "OK")
        elif m in ("GET_PARAMETER", "SET_PARAMETER"):
            # A keep-alive may name no session; one that names a session must name a live one.
            sid = _session_id(req)
            if sid and sid not in self.sessions:
                self.reply(req, 454, "Session Not Found")
                return
            self.reply(req, 200, "OK", {"Session": sid} if sid else {})
        elif m in NOT_ALLOWED:
            self.reply(req, 405, "Method Not Allowed", {"Allow": ", ".join(SUPPORTED)})
        else:
            log.warning("RTSP %s: unknown method %r: 501", self.peer, m[:20])
            self.reply(req, 501, "Not Implemented", {"Public": ", ".join(SUPPORTED)})

    def _session(self, req: _Request) -> _Session | None:
        sid = _session_id(req)
        if sid in self.sessions:
            return self.sessions[sid]
        if not sid and len(self.sessions) == 1:
            return next(iter(self.sessions.values()))
        return None

    async def _describe(self, req: _Request) -> None:
        stream = self.server.find(req.url)
        if stream is None:
            self.reply(req, 404, "Not Found")
            return
        if not stream.ready.is_set():
            stream.want_keyframe()
            with contextlib.suppress(asyncio.TimeoutError):
                await asyncio.wait_for(stream.ready.wait(), DESCRIBE_WAIT_S)
        if not stream.ready.is_set():
            self.reply(req, 503, "Service Unavailable")
            return
        host = self.server.host
        body = sdp(stream.codec, stream.params, host=host, session_id=random.getrandbits(31))
        base = req.url if req.url.endswith("/") else req.url + "/"
        self.reply(req, 200, "OK", {"Content-Base": base, "Content-Type": "application/sdp"}, body)

    async def _setup(self, req: _Request) -> None:
        stream = self.server.find(req.url)
        if stream is None:
            self.reply(req, 404, "Not Found")
            return
        if _session_id(req):
            # One track per stream, so a SETUP that names a session would change a set-up
            # session's transport, which is not offered (455); a session this connection does
            # not hold is 454 (RFC 2326 11.3.9).
            if _session_id(req) in self.sessions:
                self.reply(req, 455, "Method Not Valid in This State")
            else:
                self.reply(req, 454, "Session Not Found")
            return
        if len(stream.sessions) >= MAX_RECEIVERS:
            # Sessions count from SETUP, not PLAY: set-up sessions hold sockets, and counting only
            # playing ones let one client set up any number and then play them all.
            log.warning("RTSP %s: refusing %s: %d sessions already (limit)", stream.path, self.peer, MAX_RECEIVERS)
            self.reply(req, 453, "Not Enough Bandwidth")
            return
        busy = {c for s in self.sessions.values() if s.channel is not None for c in (s.channel, s.channel + 1)}
        wanted = parse_transport(req.headers.get("transport", ""), busy)
        if wanted is None or self.transport is None:
            log.warning(
                "RTSP %s: no usable transport in %r (unicast RTP/AVP over TCP, channels 0..255, or UDP, "
                "client ports 1..65535): 461", self.peer, req.headers.get("transport", "")[:120],
            )  # fmt: skip
            self.reply(req, 461, "Unsupported Transport")
            return
        sid = f"{random.getrandbits(48):012X}"
        pk = Packetizer(stream.codec, random.getrandbits(32), random.getrandbits(16))
        session = _Session(sid, stream, self, pk)
        # Hold the place before the first await: SETUPs on other connections meanwhile see it.
        stream.sessions.add(session)
        reply_transport = wanted.header()
        if wanted.tcp:
            session.channel = wanted.rtp
        else:
            peer_host = self.transport.get_extra_info("peername")[0]
            loop = asyncio.get_running_loop()
            local = self.transport.get_extra_info("sockname")[0]
            try:
                udp, _ = await loop.create_datagram_endpoint(lambda: _Heard(self), local_addr=(local, 0))
                session.udp = udp  # type: ignore[assignment]
                rtcp, _ = await loop.create_datagram_endpoint(lambda: _Heard(self), local_addr=(local, 0))
                session.udp_rtcp = rtcp  # type: ignore[assignment]
            except OSError as exc:  # out of sockets or ports: this SETUP fails, the server goes on
                session.close()
                log.warning("RTSP %s: cannot open UDP sockets for %s (%s): 503", stream.path, self.peer, exc)
                self.reply(req, 503, "Service Unavailable")
                return
            except BaseException:  # cancelled: the connection went away meanwhile
                session.close()
                raise
            session.udp_peer = (peer_host, wanted.rtp)
            session.server_ports = (udp.get_extra_info("sockname")[1], rtcp.get_extra_info("sockname")[1])
            reply_transport += f";server_port={session.server_ports[0]}-{session.server_ports[1]}"
            if self.transport.is_closing():  # the client left while the sockets were made
                session.close()
                return
        self.sessions[sid] = session
        self.reply(req, 200, "OK", {"Transport": reply_transport, "Session": f"{sid};timeout={SESSION_TIMEOUT_S}"})

    def _play(self, req: _Request) -> None:
        s = self._session(req)
        if s is None:
            self.reply(req, 454, "Session Not Found")
            return
        s.playing = True
        s.waiting_key = True
        s.stream.receivers.add(s)
        s.stream.want_keyframe()  # so the new receiver starts now, not at the next GOP
        s.stream.on_play()
        info = f"url={req.url.rstrip('/')}/trackID=0;seq={s.packetizer.seq};rtptime={s.stream.now_rtp()}"
        self.reply(req, 200, "OK", {"Session": s.id, "Range": "npt=0.000-", "RTP-Info": info})


def _session_id(req: _Request) -> str:
    return req.headers.get("session", "").split(";")[0].strip()


def _cseq_ok(req: _Request) -> bool:
    cseq = req.headers.get("cseq", "")
    return cseq.isascii() and cseq.isdigit() and len(cseq) <= 10


class RtspServer:
    """Serves some streams (by path) on one TCP port."""

    def __init__(self, host: str, port: int, streams: list[Stream]) -> None:
        self.host = host
        self.port = port
        self.streams = {s.path: s for s in streams}
        self.connections: set[_Connection] = set()
        self._server: asyncio.base_events.Server | None = None
        self._ids = itertools.count(1)
        self._reaper: asyncio.Task[None] | None = None

    async def start(self) -> RtspServer:
        loop = asyncio.get_running_loop()
        self._server = await loop.create_server(lambda: _Connection(self), self.host, self.port)
        self.port = self._server.sockets[0].getsockname()[1]
        self._reaper = loop.create_task(self._reap_forever())
        return self

    def reap(self, now: float | None = None) -> int:
        """Close every connection nothing was heard from for IDLE_CLOSE_S; how many were closed."""
        now = time.monotonic() if now is None else now
        closed = 0
        for c in list(self.connections):
            if now - c.last_heard > IDLE_CLOSE_S and c.transport is not None and not c.transport.is_closing():
                log.warning(
                    "RTSP %s: nothing heard for %.0f s (no request, no RTCP; the session timeout is %d s): closing",
                    c.peer, now - c.last_heard, SESSION_TIMEOUT_S,
                )  # fmt: skip
                c.transport.close()
                closed += 1
        return closed

    async def _reap_forever(self) -> None:
        while True:
            await asyncio.sleep(REAP_EVERY_S)
            self.reap()

    def find(self, url: str) -> Stream | None:
        path = urlsplit(url).path if "://" in url else url
        path = path.rstrip("/")
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
                await asyncio.wait_for(self._server.wait_closed(), 2.0)
            self._server = None
