"""Where Cursor-on-Target goes: `udp://HOST:PORT` (TAK's mesh: one event per datagram, lost when
nobody listens), `tcp://HOST:PORT` or `tls://HOST:PORT` (a TAK server's streaming input, e.g.
8087 and 8089; TLS with a client certificate, checked against the given CA).

A stream never holds the bridge up: `offer()` only queues. A task connects, writes the queue out
and reads (and drops) what the server sends; on a loss it keeps the newest QUEUE_EVENTS events
(older ones are dropped and counted: a TAK map wants the latest position, not a backlog), waits
1, 2, 4 ... BACKOFF_MAX_S seconds between attempts, and says once when the link is lost and once
when it is back (how long, how many events were kept and dropped)."""

from __future__ import annotations

import asyncio
import contextlib
import logging
import socket
import ssl
from collections import deque
from dataclasses import dataclass
from urllib.parse import urlsplit

from ..clock import monotonic
from ..errors import TopGimbalError
from ..timeouts import within

log = logging.getLogger("topgimbal.mavlink")

SCHEMES = ("udp", "tcp", "tls")
QUEUE_EVENTS = 30  # about 10 s of one camera's three events a second
BACKOFF_MAX_S = 10.0  # a map wants the vehicle back soon; one attempt per 10 s costs nothing
CONNECT_TIMEOUT_S = 10.0
WRITE_TIMEOUT_S = 10.0  # a server that stops reading this long counts as lost


class CotConfigError(TopGimbalError, ValueError):
    kind = "cot"


@dataclass(frozen=True)
class CotTls:
    """A TAK server's TLS input: the client certificate and key (PEM; TAK servers ask for one),
    the CA that signed the server's certificate (PEM; None: the system's CAs) and the name that
    certificate must carry (None: the URL's host; a TAK server reached by address often has a
    certificate for its host name only, e.g. OpenTAKServer's `opentakserver`)."""

    cert: str | None = None
    key: str | None = None
    ca: str | None = None
    server_name: str | None = None


@dataclass(frozen=True)
class CotTarget:
    scheme: str
    host: str
    port: int

    def __str__(self) -> str:
        return f"{self.scheme}://{self.host}:{self.port}" if ":" not in self.host else \
            f"{self.scheme}://[{self.host}]:{self.port}"  # fmt: skip


def parse_url(url: str) -> CotTarget:
    """udp://, tcp:// or tls://HOST:PORT -> CotTarget; CotConfigError otherwise."""
    try:
        parts = urlsplit(url)
        port = parts.port
    except ValueError:
        port = None
        parts = urlsplit("")
    if parts.scheme not in SCHEMES or not parts.hostname or port is None:
        raise CotConfigError(f"CoT target {url!r}: expected udp://HOST:PORT (e.g. TAK's mesh udp://239.2.3.1:6969), "
                             "tcp://HOST:PORT or tls://HOST:PORT (a TAK server, e.g. 8087 / 8089)")  # fmt: skip
    return CotTarget(parts.scheme, parts.hostname, port)


def ssl_context(target: CotTarget, tls: CotTls | None) -> ssl.SSLContext | None:
    """The client context for tls:// (None for udp and tcp); CotConfigError for files it cannot use,
    read now so a wrong path stops the start, not the first send."""
    t = tls or CotTls()
    if target.scheme != "tls":
        if t.cert or t.key or t.ca or t.server_name:
            raise CotConfigError(f"CoT target {target}: a client certificate or CA is for tls:// only")
        return None
    if bool(t.cert) != bool(t.key):
        raise CotConfigError("CoT over TLS: give the client certificate and its key together")
    try:
        ctx = ssl.create_default_context(ssl.Purpose.SERVER_AUTH, cafile=t.ca)
    except (OSError, ssl.SSLError) as exc:
        raise CotConfigError(f"CoT over TLS: the CA file {t.ca!r} cannot be used: {exc}") from None
    if t.cert and t.key:
        try:
            ctx.load_cert_chain(t.cert, t.key)
        except (OSError, ssl.SSLError) as exc:
            raise CotConfigError(f"CoT over TLS: the client certificate {t.cert!r} / key {t.key!r} cannot be used: "
                                 f"{exc}") from None  # fmt: skip
    return ctx


class UdpOut:
    """One event per datagram; a full socket buffer drops that one (the next second brings more)."""

    def __init__(self, target: CotTarget) -> None:
        self.target = target
        self.sent = self.dropped = 0
        self._sock: socket.socket | None = None

    def offer(self, data: bytes) -> None:
        if self._sock is None:
            self._sock = socket.socket(socket.AF_INET6 if ":" in self.target.host else socket.AF_INET,
                                       socket.SOCK_DGRAM)  # fmt: skip
            self._sock.setblocking(False)
            if self.target.host.startswith("239."):
                self._sock.setsockopt(socket.IPPROTO_IP, socket.IP_MULTICAST_TTL, 1)  # TAK's mesh stays on the LAN
        try:
            self._sock.sendto(data, (self.target.host, self.target.port))
            self.sent += 1
        except BlockingIOError:
            self.dropped += 1

    async def run(self) -> None:
        await asyncio.Event().wait()  # nothing to keep up: sends happen in offer()

    def close(self) -> None:
        if self._sock is not None:
            self._sock.close()
            self._sock = None


class StreamOut:
    """A TAK server's TCP or TLS streaming input (plain XML events one after another), reconnected."""

    def __init__(
        self, target: CotTarget, ctx: ssl.SSLContext | None, *, queue_events: int = QUEUE_EVENTS,
        server_name: str | None = None,
    ) -> None:  # fmt: skip
        self.target, self.ctx, self.server_name = target, ctx, server_name
        self.queue: deque[bytes] = deque(maxlen=queue_events)
        self.sent = self.dropped = self.connects = 0
        self.connected = False
        self._ready = asyncio.Event()
        self._dropped_at_loss = 0

    def offer(self, data: bytes) -> None:
        if len(self.queue) == self.queue.maxlen:
            self.dropped += 1  # the oldest goes: a map wants where things are now
        self.queue.append(data)
        self._ready.set()

    async def run(self) -> None:
        backoff_s, lost_at, failures = 1.0, None, 0
        while True:
            try:
                reader, writer = await within(
                    asyncio.open_connection(
                        self.target.host,
                        self.target.port,
                        ssl=self.ctx,
                        server_hostname=self.server_name if self.ctx else None,
                    ),
                    CONNECT_TIMEOUT_S,
                )
            except (OSError, asyncio.TimeoutError, ssl.SSLError) as exc:
                if failures == 0:
                    log.warning("CoT %s: cannot connect (%s): keeping the newest %d events, trying again",
                                self.target, _why(exc), self.queue.maxlen)  # fmt: skip
                failures += 1
                lost_at = monotonic() if lost_at is None else lost_at
                await asyncio.sleep(backoff_s)
                backoff_s = min(BACKOFF_MAX_S, backoff_s * 2)
                continue
            self.connected, self.connects = True, self.connects + 1
            if lost_at is not None:
                log.warning("CoT %s: connected again after %.0f s: %d events kept to send, %d dropped meanwhile",
                            self.target, monotonic() - lost_at, len(self.queue),
                            self.dropped - self._dropped_at_loss)  # fmt: skip
            else:
                log.info("CoT %s: connected", self.target)
            lost_at, failures, connected_at = None, 0, monotonic()
            why = await self._serve(reader, writer)
            self.connected = False
            lost_at, self._dropped_at_loss = monotonic(), self.dropped
            log.warning("CoT %s: connection lost (%s): keeping the newest %d events, reconnecting",
                        self.target, why, self.queue.maxlen)  # fmt: skip
            # a server that takes the connection and drops it at once (a refused certificate, a full
            # server) is tried ever more slowly too; one that served a while, at once again
            backoff_s = 1.0 if lost_at - connected_at >= BACKOFF_MAX_S else min(BACKOFF_MAX_S, backoff_s * 2)
            await asyncio.sleep(backoff_s)

    async def _serve(self, reader: asyncio.StreamReader, writer: asyncio.StreamWriter) -> str:
        """Write the queue out until the connection fails; what failed."""
        eof = asyncio.ensure_future(_drain_reader(reader))  # a TAK server sends others' events; unread, it stalls
        try:
            while True:
                while not self.queue:
                    self._ready.clear()
                    waiter = asyncio.ensure_future(self._ready.wait())
                    done, _ = await asyncio.wait({waiter, eof}, return_when=asyncio.FIRST_COMPLETED)
                    if eof in done:
                        waiter.cancel()
                        return "closed by the server"
                data = self.queue[0]
                writer.write(data)
                try:
                    await within(writer.drain(), WRITE_TIMEOUT_S)
                except asyncio.TimeoutError:
                    return f"the server read nothing for {WRITE_TIMEOUT_S:.0f} s"
                except (OSError, ssl.SSLError) as exc:
                    return _why(exc)  # the event stays queued: sent again after the reconnect
                if self.queue and self.queue[0] is data:
                    self.queue.popleft()
                self.sent += 1
        finally:
            eof.cancel()
            writer.close()
            with contextlib.suppress(Exception):
                await within(writer.wait_closed(), 2.0)

    def close(self) -> None:
        pass  # the connection closes with run()'s cancellation


async def _drain_reader(reader: asyncio.StreamReader) -> None:
    with contextlib.suppress(OSError, ssl.SSLError):
        while await reader.read(65536):
            pass


def _why(exc: BaseException) -> str:
    return "timed out" if isinstance(exc, asyncio.TimeoutError) else str(exc) or type(exc).__name__


def open_out(url: str, tls: CotTls | None = None) -> UdpOut | StreamOut:
    target = parse_url(url)
    ctx = ssl_context(target, tls)
    return (
        UdpOut(target)
        if target.scheme == "udp"
        else StreamOut(target, ctx, server_name=tls.server_name if tls else None)
    )
