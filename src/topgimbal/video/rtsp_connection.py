"""One RTSP connection of the server in rtsp.py (the module docstring there says what is served and
the bounds): requests parsed and answered in order (at most MAX_PIPELINED waiting, MAX_REQUEST_BYTES
each), DESCRIBE / SETUP / PLAY / TEARDOWN and the keep-alives, its sessions (MAX_RECEIVERS per
stream), RTP interleaved or over UDP, and at most MAX_BUFFERED_BYTES unsent. It sees its server only
through `RtspOwner`: the peer table, the connection limit, the host, `find(url)`."""

from __future__ import annotations

import asyncio
import contextlib
import logging
import random
from typing import Any, Protocol

from ..logtext import untrusted
from ..peers import PeerTable
from ..timeouts import within
from .rtp import Packetizer, sdp
from .rtsp_request import BadUrlError, Request, cseq_ok, parse_transport, session_id
from .rtsp_stream import Session, Stream

log = logging.getLogger("topgimbal.video.rtsp")

MAX_RECEIVERS = 8
MAX_REQUEST_BYTES = 8192
MAX_PIPELINED = 32  # requests waiting for an answer on one connection
MAX_BUFFERED_BYTES = 2_000_000
DESCRIBE_WAIT_S = 5.0
SESSION_TIMEOUT_S = 60  # advertised in SETUP's Session header: clients keep alive within it
SERVER_NAME = "topgimbal-sim"
SUPPORTED = ("OPTIONS", "DESCRIBE", "SETUP", "PLAY", "TEARDOWN", "GET_PARAMETER", "SET_PARAMETER")
# RTSP methods this server knows but does not offer (405 with Allow); anything else is 501.
NOT_ALLOWED = ("ANNOUNCE", "PAUSE", "RECORD", "REDIRECT", "PLAY_NOTIFY")
MAX_CHANNEL = 254  # interleaved RTP channel; RTCP takes the next one, and both must fit in a byte


class RtspOwner(Protocol):
    """What a connection reads of its server (rtsp.RtspServer)."""

    connections: PeerTable[RtspConnection, RtspConnection]
    host: str

    @property
    def max_connections(self) -> int: ...

    def find(self, url: str) -> Stream | None: ...


class _Heard(asyncio.DatagramProtocol):
    """RTCP receiver reports and NAT probes arrive here: they only show the receiver is alive."""

    def __init__(self, conn: RtspConnection) -> None:
        self.conn = conn

    def datagram_received(self, data: bytes, addr: tuple[str | Any, int]) -> None:
        self.conn.heard()


class RtspConnection(asyncio.Protocol):
    """One RTSP connection: its requests answered in order, its sessions, its bounds."""

    def __init__(self, server: RtspOwner) -> None:
        self.server = server
        self.transport: asyncio.Transport | None = None
        self.peer: str = "?"
        self.buf = b""
        self.sessions: dict[str, Session] = {}
        # Stream path -> the codec generation its last DESCRIBE on this connection told (bounded
        # by the server's streams): a SETUP after the encoder restarted would play another codec
        # than the client's SDP says (a player then decodes nothing, ffprobe waited for ever).
        self.described: dict[str, int] = {}
        self.queue: asyncio.Queue[Request] = asyncio.Queue()
        self.task: asyncio.Task[None] | None = None
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
        self.server.connections.heard(self)

    @property
    def last_heard(self) -> float | None:
        """When the client was last heard (the server's clock); None once it is not served."""
        return self.server.connections.heard_at(self)

    def connection_made(self, transport: asyncio.BaseTransport) -> None:
        self.transport = transport  # type: ignore[assignment]
        peer = transport.get_extra_info("peername")
        self.peer = f"{peer[0]}:{peer[1]}" if peer else "?"
        table = self.server.connections
        table.cap = self.server.max_connections  # rtsp.MAX_CONNECTIONS, read at each connection
        if not table.admit(self, self):  # refused at the cap: counted, logged (throttled) by the table
            transport.close()
            return
        if self.transport is not None:
            self.transport.set_write_buffer_limits(high=MAX_BUFFERED_BYTES, low=MAX_BUFFERED_BYTES // 2)
        self.task = asyncio.get_running_loop().create_task(self._serve())

    def connection_lost(self, exc: Exception | None) -> None:
        self.server.connections.forget(self)
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
            self.queue.put_nowait(Request(parts[0].upper(), parts[1], headers, parts[2]))

    def _unsent(self) -> int:
        return self.transport.get_write_buffer_size() if self.transport is not None else 0

    def _bad(self, why: str) -> None:
        log.warning("RTSP %s: %s; closing", self.peer, untrusted(why))
        self.reply(Request("?", "", {}), 400, "Bad Request")
        self.buf = b""
        if self.transport is not None:
            self.transport.close()

    def reply(
        self, req: Request, code: int, reason: str, headers: dict[str, str] | None = None, body: str = ""
    ) -> None:
        if self.transport is None or self.transport.is_closing():
            return
        lines = [f"RTSP/1.0 {code} {reason}"]
        if cseq_ok(req):
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
                log.exception("RTSP %s: %s failed", self.peer, untrusted(req.method, 20))
                self.reply(req, 500, "Internal Server Error")

    # -- methods ----------------------------------------------------------------------------------

    async def _handle(self, req: Request) -> None:
        m = req.method
        # RFC 2326 12.17: every request carries CSeq; RFC 7826 7.1.1: a version the server does
        # not speak is 505. Both answers keep the connection (the request itself was framed).
        if not cseq_ok(req):
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
            sid = session_id(req)
            if sid and sid not in self.sessions:
                self.reply(req, 454, "Session Not Found")
                return
            self.reply(req, 200, "OK", {"Session": sid} if sid else {})
        elif m in NOT_ALLOWED:
            self.reply(req, 405, "Method Not Allowed", {"Allow": ", ".join(SUPPORTED)})
        else:
            log.warning("RTSP %s: unknown method %r: 501", self.peer, m[:20])
            self.reply(req, 501, "Not Implemented", {"Public": ", ".join(SUPPORTED)})

    def _session(self, req: Request) -> Session | None:
        sid = session_id(req)
        if sid in self.sessions:
            return self.sessions[sid]
        if not sid and len(self.sessions) == 1:
            return next(iter(self.sessions.values()))
        return None

    def _stream(self, req: Request) -> Stream | None:
        """The stream a request names; None after answering 400 (a URL that cannot be parsed)
        or 404 (no such path)."""
        try:
            stream = self.server.find(req.url)
        except BadUrlError as exc:
            log.warning("RTSP %s: %s with an unparsable URL %r (%s): 400", self.peer, req.method, req.url[:120], exc)
            self.reply(req, 400, "Bad Request")
            return None
        if stream is None:
            self.reply(req, 404, "Not Found")
        return stream

    async def _describe(self, req: Request) -> None:
        stream = self._stream(req)
        if stream is None:
            return
        if not stream.ready.is_set():
            stream.want_keyframe()
            with contextlib.suppress(asyncio.TimeoutError):
                await within(stream.ready.wait(), DESCRIBE_WAIT_S)
        if not stream.ready.is_set():
            self.reply(req, 503, "Service Unavailable")
            return
        host = self.server.host
        self.described[stream.path] = stream.generation
        body = sdp(stream.codec, stream.params, host=host, session_id=random.getrandbits(31))
        base = req.url if req.url.endswith("/") else req.url + "/"
        self.reply(req, 200, "OK", {"Content-Base": base, "Content-Type": "application/sdp"}, body)

    async def _setup(self, req: Request) -> None:
        stream = self._stream(req)
        if stream is None:
            return
        if session_id(req):
            # One track per stream, so a SETUP that names a session would change a set-up
            # session's transport, which is not offered (455); a session this connection does
            # not hold is 454 (RFC 2326 11.3.9).
            if session_id(req) in self.sessions:
                self.reply(req, 455, "Method Not Valid in This State")
            else:
                self.reply(req, 454, "Session Not Found")
            return
        told = self.described.get(stream.path)
        if told is not None and told != stream.generation:
            # The codec changed between this client's DESCRIBE and its SETUP: its SDP is stale.
            # 503: describe again (what a player does on a failed SETUP, and the new SDP is right).
            log.info("RTSP %s: %s set up after the codec changed to %s since its DESCRIBE: 503 (describe again)",
                     stream.path, self.peer, stream.codec)  # fmt: skip
            self.reply(req, 503, "Service Unavailable")
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
        session = Session(sid, stream, self, pk)
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
                session.udp = udp
                rtcp, _ = await loop.create_datagram_endpoint(lambda: _Heard(self), local_addr=(local, 0))
                session.udp_rtcp = rtcp
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

    def _play(self, req: Request) -> None:
        s = self._session(req)
        if s is None:
            self.reply(req, 454, "Session Not Found")
            return
        if not s.playing:  # a PLAY on a playing session changes nothing (RFC 2326 10.5)
            s.playing = True
            s.waiting_key = True
            s.stream.receivers.add(s)
            # So the new receiver starts now rather than at the next GOP: rate limited per stream
            # (rtsp_stream.KEYFRAME_MIN_INTERVAL_S), as the keyframe goes to every receiver.
            s.stream.want_keyframe()
            s.stream.on_play()
        info = f"url={req.url.rstrip('/')}/trackID=0;seq={s.packetizer.seq};rtptime={s.stream.now_rtp()}"
        self.reply(req, 200, "OK", {"Session": s.id, "Range": "npt=0.000-", "RTP-Info": info})
