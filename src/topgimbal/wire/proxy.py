"""The proxy: sits between a ground station (or vendor app) and a camera, forwards every byte both
ways unchanged, and decodes what passes.

    proxy = Proxy("udp://127.0.0.1:5600", "udp://127.0.0.1:5000", pcap="s.pcap", log="s.jsonl")
    unsubscribe = proxy.subscribe(lambda event: print(event.direction, event.item))
    await proxy.start(); ...; await proxy.stop()

Forwarding comes first: a chunk is sent on before it is decoded, logged or shown. What happens
after (`watcher.Watcher`: frames found, captured, decoded once, logged, published) runs either
here, in steps between datagrams (subscribers run on this loop), or with `offload=` in a watcher
process of its own (`offload.WatcherProcess`: `topgimbal proxy` does this, so the forwarding
process stays as light as forwarding alone; subscribers are then not available). Between a stream side (TCP, serial) and a datagram side (UDP) bytes are
sent on at frame boundaries (what the frame parser has consumed), so each datagram holds whole
frames; bytes the parser still holds are sent as they are after `STREAM_FLUSH_S` of silence.

Bounded: at most `max_clients` clients (UDP: the least recently active is dropped for a new one;
TCP: a connection beyond the limit is closed), UDP clients idle for `idle_timeout_s` are
forgotten, at most `MAX_QUEUED` bytes wait per client while its device link opens (a TCP client
is not read beyond it) and at most that much unread by a TCP client (it is aborted) or unsent
towards a stream device (TCP: the session ends; a serial line: chunks are dropped), at most
`MAX_BACKLOG` bytes wait to be decoded (beyond, chunks are still forwarded but not decoded,
logged or captured; counted), at most `MAX_SUBSCRIBERS` subscribers. Every limit hit is logged
(what peers can repeat at will, at most once per `LOG_EVERY_S`). A serial device has one host at
a time, so with `to=serial://` a new client replaces the previous one.

The pcap shows the device's side of the proxy as if captured on that link: the client's address
talking to the device's (a serial side is given loopback addresses and the dialect's documented
port, so Wireshark picks the right dialect). The traffic log is the client SDK's JSONL format.
"""

from __future__ import annotations

import asyncio
import logging
from collections.abc import Callable, Hashable
from pathlib import Path
from typing import Any

from ..clock import wall_time
from ..peers import EVICT, EVICTED, EXPIRED, REFUSE, Gone, PeerTable, Words
from ..protocol import Dialect
from ..transport import Transport, TransportURL, open_transport, parse_url
from ..transport.tcp import StreamTransport
from .backlog import MAX_BACKLOG, Backlog
from .offload import WatcherProcess
from .packets import Endpoint
from .proxy_setup import choose_dialect, device_endpoint, listen_url, watcher_config
from .sessions import MAX_QUEUED, Session, TcpClient, Throttle, ep_text
from .udplink import UdpSocket
from .watcher import (
    CLOSED,
    MAX_SUBSCRIBERS,
    Chunk,
    ProxyError,
    ProxyEvent,
    ProxyStats,
    Subscriber,
    Watcher,
)

log = logging.getLogger("topgimbal.proxy")

MAX_CLIENTS = 8
IDLE_TIMEOUT_S = 120.0
STREAM_FLUSH_S = 0.05
FLUSH_S = 0.2  # the pcap and the log are handed to the files this often (and at stop)
SERIAL_CLIENT: Endpoint = ("127.0.0.1", 40000)
SERIAL_KEY = ("serial",)
# The client table's lines (peers.py: throttled per LOG_EVERY_S, the next one counting the rest).
WORDS = Words(
    refused="proxy: at most {cap} clients; refusing {newcomer}",
    evicted="proxy: at most {cap} client(s); dropping {peer} for {newcomer}",
)


class Proxy:
    """Forward `listen` <-> `to` (udp://, tcp://, serial:// on either side), decoding both ways."""

    def __init__(
        self,
        listen: str,
        to: str,
        *,
        dialect: str | None = None,
        model: str | None = None,
        pcap: str | Path | None = None,
        log_path: str | Path | None = None,
        max_clients: int = MAX_CLIENTS,
        idle_timeout_s: float = IDLE_TIMEOUT_S,
        offload: WatcherProcess | None = None,
    ) -> None:
        self.listen: TransportURL = parse_url(listen)
        self.to: TransportURL = parse_url(to)
        if max_clients < 1:
            raise ProxyError(f"max_clients={max_clients}: at least 1")
        self.model = model
        self.dialect: Dialect | None = choose_dialect(model, dialect, (self.to, self.listen))
        self.max_clients = 1 if self.to.scheme == "serial" else max_clients
        self.idle_timeout_s = idle_timeout_s
        self.pcap_path = Path(pcap) if pcap else None
        self.log_path = Path(log_path) if log_path else None
        self.stats = ProxyStats()
        self.throttle = Throttle()
        # The clients, in the shared peer table (peers.py): a UDP client (or the one host of a
        # serial device) takes the place of the least recently active one, a TCP connection
        # beyond the cap is refused; UDP clients idle for idle_timeout_s are forgotten.
        refuse = self.listen.scheme == "tcp" and self.to.scheme != "serial"
        self._sessions: PeerTable[Hashable, Session] = PeerTable(
            self.max_clients,
            at_cap=REFUSE if refuse else EVICT,
            lease_s=idle_timeout_s if self.listen.scheme == "udp" else 0.0,
            name="proxy",
            throttle=self.throttle,
            words=WORDS,
            describe=self._client_label,
            on_gone=self._client_gone,
        )
        self._flusher: asyncio.TimerHandle | None = None
        self._udp: UdpSocket | None = None
        self._server: asyncio.AbstractServer | None = None
        self._serial: Transport | None = None
        self._serial_dropped = 0  # chunks dropped since the serial line last kept up
        self._closing: dict[asyncio.Task[None], Session] = {}  # sessions ending (some deliver first)
        self._sweeper: asyncio.TimerHandle | None = None
        self._device_ep: Endpoint = ("127.0.0.1", 0)
        self._transport_kind = self.to.scheme if self.to.scheme in ("udp", "tcp") else self.listen.scheme
        if self._transport_kind == "serial":
            self._transport_kind = "udp"
        self.listen_address: tuple[str, int] | None = None
        log_header = {
            "url": self.to.text,
            "model": self.model or "",
            "dialect": self.dialect.name if self.dialect else "",
        }
        # what happens to traffic after it is forwarded: here (in steps between datagrams), or in
        # a process of its own (`offload`, the CLI's choice: the forwarding process stays light)
        self.watcher = Watcher(
            dialect=self.dialect,
            device=self._device_ep,
            transport=self._transport_kind,
            pcap=self.pcap_path,
            log_path=self.log_path,
            log_header=log_header,
            stats=self.stats,
        )
        self.offload = offload
        self.backlog = Backlog(self.watcher, self.stats)

    # -- subscribers ------------------------------------------------------------------------------

    def subscribe(self, callback: Subscriber) -> Callable[[], None]:
        """Call `callback(event)` for every frame that crosses the proxy; returns the function that
        unsubscribes. Callbacks run on the proxy's event loop: keep them short. An exception in one
        is logged and counted, never passed on. At most MAX_SUBSCRIBERS; not with `offload` (the
        frames are decoded in another process)."""
        if self.offload is not None:
            raise ProxyError("subscribers run in the proxy's process; this proxy decodes in a watcher process")
        return self.watcher.subscribe(callback)

    # -- lifecycle --------------------------------------------------------------------------------

    @property
    def url(self) -> str:
        """Where clients connect (the real port when the listen URL said 0)."""
        return listen_url(self.listen, self.listen_address)

    async def start(self) -> None:
        loop = asyncio.get_running_loop()
        self._device_ep = self.watcher.device = await device_endpoint(self.to, self.dialect)  # as the pcap shows it
        if self.offload is not None:
            await self.offload.start(watcher_config(self.watcher, self.model, self.dialect))
        else:
            self.watcher.open()
            if self.watcher.writes_files:
                self._flusher = loop.call_later(FLUSH_S, self._flush_timer)
        try:
            if self.listen.scheme == "udp":
                self._udp = await UdpSocket.bind(self.listen.host, self.listen.port or 0, self._udp_datagram)
                self.watch(self._udp)
                self.listen_address = self._udp.address
                self._sweeper = loop.call_later(min(self.idle_timeout_s, 5.0), self._sweep)
            elif self.listen.scheme == "tcp":
                self._server = await loop.create_server(
                    lambda: TcpClient(self), self.listen.host, self.listen.port or 0, reuse_address=True
                )
                self.listen_address = self._server.sockets[0].getsockname()[:2]
            else:
                session = Session(self, f"serial {self.listen.path}", SERIAL_CLIENT, self._serial_send)
                self._serial = await open_transport(self.listen, session.from_client, self._serial_lost)
                self._add(SERIAL_KEY, session)
        except OSError as exc:
            await self.stop()
            raise ProxyError(f"cannot listen on {self.listen}: {exc.strerror or exc}") from None
        log.info("proxy: %s -> %s", self.url, self.to)

    async def stop(self) -> None:
        if self._sweeper is not None:
            self._sweeper.cancel()
        if self._flusher is not None:
            self._flusher.cancel()
            self._flusher = None
        self.drain()
        for session in self._sessions.clear():
            await session.close()
        for task, session in list(self._closing.items()):  # stopping: no more waiting for device links
            if session.opening is not None:
                session.opening.cancel()
            await asyncio.gather(task, return_exceptions=True)
        if self._udp is not None:
            await self._udp.close()
        if self._server is not None:
            self._server.close()
            await self._server.wait_closed()
        if self._serial is not None:
            await self._serial.close()
        self.drain()
        if self.offload is not None:
            counted = await self.offload.stop()
            self.stats.backlog_dropped += self.offload.dropped
            for key in ("frames_out", "frames_in", "bytes_out", "bytes_in", "subscriber_errors"):
                setattr(self.stats, key, getattr(self.stats, key) + int(counted.get(key, 0)))
        self.watcher.close()  # writes what waits

    async def __aenter__(self) -> Proxy:
        await self.start()
        return self

    async def __aexit__(self, *exc: object) -> None:
        await self.stop()

    # -- clients ----------------------------------------------------------------------------------

    def _add(self, key: Hashable, session: Session) -> None:
        admitted = self._sessions.admit(key, session)  # at the cap: EVICT made room, REFUSE was asked first
        assert admitted, "tcp_connected makes room before a session is made"
        session.key = key
        self.stats.clients += 1
        session.opening = asyncio.get_running_loop().create_task(session.open())

    def _client_label(self, key: Hashable) -> str:
        """How the log names a client: its session's label ("udp 127.0.0.1:53012")."""
        session = self._sessions.get(key)
        if session is not None:
            return session.label
        if key == SERIAL_KEY:
            return f"serial {self.listen.path}"
        return f"{self.listen.scheme} {ep_text(key)}" if isinstance(key, tuple) else str(key)

    def _client_gone(self, gone: Gone[Hashable, Session]) -> None:
        """A client evicted for a newcomer or idle for the lease: its session ends (drop() ends
        the ones it forgets itself)."""
        if gone.why == EVICTED:
            self.stats.clients_dropped += 1
        elif gone.why == EXPIRED:
            idle_s = self._sessions.clock() - gone.heard_s
            log.info("proxy: %s idle for %.0f s; forgotten", gone.value.label, idle_s)
        else:
            return
        asyncio.get_running_loop().create_task(gone.value.close())

    def heard(self, session: Session) -> None:
        """Traffic of `session` (the device's side; the client's is renewed where it arrives):
        it is active, so the last to be evicted and not idle."""
        key = session.key
        if key is not None and self._sessions.get(key) is session:
            self._sessions.heard(key)

    def drop(self, session: Session, *, deliver: bool = False) -> None:
        if session.key is not None:
            self._sessions.forget(session.key, session)
        if not session.closed:
            task = asyncio.get_running_loop().create_task(session.close(deliver))
            self._closing[task] = session
            task.add_done_callback(lambda t: self._closing.pop(t, None))

    def _udp_datagram(self, data: bytes, addr: tuple[Any, ...]) -> None:
        key = addr[:2]
        session = self._sessions.heard(key)  # renewed: the most recently active now
        if session is None:
            label = f"udp {ep_text(key)}"
            udp = self._udp

            def send_down(payload: bytes, addr: tuple[Any, ...] = addr) -> None:
                if udp is not None:
                    udp.sendto(payload, addr)

            session = Session(self, label, (str(addr[0]), int(addr[1])), send_down)
            self._add(key, session)
        session.from_client(data)

    def tcp_connected(self, client: TcpClient) -> Session | None:
        assert client.transport is not None
        peer = client.transport.get_extra_info("peername")[:2]
        if not self._sessions.make_room(peer):  # refused at the cap: counted and logged by the table
            client.transport.close()
            return None
        session = Session(
            self, f"tcp {ep_text(peer)}", (str(peer[0]), int(peer[1])), client.send, client.close, client.pause
        )
        self._add(peer, session)
        return session

    def _serial_send(self, data: bytes) -> None:
        if self._serial is not None and self._serial.connected:
            unsent = self._serial.write_buffer_size if isinstance(self._serial, StreamTransport) else 0
            if unsent > MAX_QUEUED:
                # the device sends faster than the line's baud rate carries: whole chunks are dropped
                # throttled, not once per overflow: a line hovering at the bound would log each time
                self._serial_dropped += 1
                self.throttle.warning(
                    "serial-full",
                    "proxy: serial port %s has %d unsent bytes; dropping chunks",
                    self.listen.path,
                    unsent,
                )
                return
            self._serial_dropped = 0
            self._serial.send(data)

    def _serial_lost(self, exc: Exception | None) -> None:
        log.warning("proxy: serial port %s closed%s", self.listen.path, f": {exc}" if exc else "")

    def _sweep(self) -> None:
        self._sessions.expire()  # each idle one is logged and closed by _client_gone
        self._sweeper = asyncio.get_running_loop().call_later(min(self.idle_timeout_s, 5.0), self._sweep)

    # -- the data path: forwarded at once, decoded soon (backlog.py) -----------------------------

    def relay(self, session: Session, direction: str, data: bytes, send: Callable[[bytes], None]) -> None:
        """Forward `data` now; decode, record and publish it soon."""
        d = session.dirs[direction]
        t = wall_time()
        if not (d.to_datagram and not d.from_datagram):
            send(data)
            self._queue(Chunk(t, session.label, session.endpoint, direction, data, d.from_datagram, None))
            return
        # stream -> datagram: send what the parser has consumed (whole frames), hold the rest
        items = d.parser.feed(data)
        held = d.held + data
        ready = len(held) - d.parser.buffered
        if ready > 0:
            send(held[:ready])
        d.held = held[ready:]
        if d.flush_timer is not None:
            d.flush_timer.cancel()
            d.flush_timer = None
        if d.held:
            d.flush_timer = asyncio.get_running_loop().call_later(
                STREAM_FLUSH_S, self._flush_held, session, direction, send
            )
        self._queue(
            Chunk(t, session.label, session.endpoint, direction, held[:ready] if ready > 0 else b"", False, items)
        )

    def _flush_held(self, session: Session, direction: str, send: Callable[[bytes], None]) -> None:
        d = session.dirs[direction]
        d.flush_timer = None
        if d.held and not session.closed:
            send(d.held)
            self._queue(Chunk(wall_time(), session.label, session.endpoint, direction, d.held, False, d.parser.flush()))
            d.held = b""

    def _queue(self, work: Chunk) -> None:
        if self.offload is not None:
            self.offload.submit(work)
        else:
            self.backlog.queue(work)

    def watch(self, sock: UdpSocket, on: bool = True) -> None:
        self.backlog.watch(sock, on)

    def drain(self) -> None:
        """Process everything that waits now (stop() does; tests and tools may too)."""
        self.backlog.drain()

    def flush(self) -> None:
        """Hand what the pcap and the log hold to their files (a timer does this every FLUSH_S)."""
        self.watcher.flush()

    def _flush_timer(self) -> None:
        self.flush()
        self._flusher = asyncio.get_running_loop().call_later(FLUSH_S, self._flush_timer)

    def session_closed(self, session: Session) -> None:
        """A session ended: its parsers go, and its TCP connection in the pcap ends after what it sent."""
        self._queue(Chunk(wall_time(), session.label, session.endpoint, CLOSED, b"", False, []))


__all__ = [
    "FLUSH_S",
    "MAX_BACKLOG",
    "MAX_CLIENTS",
    "MAX_SUBSCRIBERS",
    "Proxy",
    "ProxyError",
    "ProxyEvent",
    "ProxyStats",
    "Subscriber",
]
