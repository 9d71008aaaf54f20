"""What the proxy does with traffic after forwarding it: find the frames, capture the packets,
decode each frame once, log it and hand it to subscribers.

The proxy forwards a chunk of bytes and hands the `Watcher` a `Chunk` (plain data: it can cross
to another process). `Watcher.steps(chunk)` does the work in steps of a few tens of microseconds,
so the proxy's event loop can forward a waiting datagram between two steps; `offload.py` runs a
Watcher in a process of its own instead, for `topgimbal proxy`.
"""

from __future__ import annotations

import contextlib
import logging
from collections.abc import Callable, Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import NamedTuple

from ..errors import TopGimbalError
from ..protocol import Diagnostic, Dialect, Frame, FrameParser, Message, decode_any, get_dialect
from .batchlog import BatchedTrafficLog
from .packets import Endpoint
from .synth import CaptureWriter

log = logging.getLogger("topgimbal.proxy")

OUT, IN = "out", "in"  # client -> device, device -> client (the traffic log's words)
CLOSED = "closed"  # a session's end, queued behind its last bytes
MAX_SUBSCRIBERS = 32


class ProxyError(TopGimbalError):
    """The proxy cannot start as asked."""


@dataclass(frozen=True)
class ProxyEvent:
    """One frame (or what the parser says about bytes that are not one) that crossed the proxy."""

    t: float  # wall clock, seconds
    direction: str  # "out": client -> device; "in": device -> client
    client: str  # which client ("udp 127.0.0.1:53012", "tcp ...", "serial ...")
    item: Frame | Diagnostic
    dialect: Dialect | None  # the dialect that decoded the frame (None for diagnostics)
    message: Message | None  # the frame decoded once, by `decode_any` (None for diagnostics)


Subscriber = Callable[[ProxyEvent], None]


@dataclass
class ProxyStats:
    frames_out: int = 0
    frames_in: int = 0
    bytes_out: int = 0
    bytes_in: int = 0
    clients: int = 0
    clients_dropped: int = 0
    subscriber_errors: int = 0
    backlog_dropped: int = 0

    def as_dict(self) -> dict[str, int]:
        return dict(self.__dict__)


class Chunk(NamedTuple):
    """Bytes that crossed the proxy (already forwarded), or the end of a client's session."""

    t: float  # wall clock when they crossed
    client: str  # the session's label: one parser per client and direction
    endpoint: Endpoint  # the client's address as the pcap shows it
    direction: str  # OUT, IN or CLOSED
    data: bytes
    from_datagram: bool  # the bytes came as one datagram (the parser ends a frame with it)
    items: list[Frame | Diagnostic] | None  # frames already found by the proxy, or None


class Watcher:
    """Parsers per client and direction, the pcap, the log, subscribers and the counters.
    `dialect` is preferred when decoding (`decode_any`); files are written in batches (`flush()`)."""

    def __init__(
        self,
        *,
        dialect: Dialect | None,
        device: Endpoint,
        transport: str,
        pcap: str | Path | None = None,
        log_path: str | Path | None = None,
        log_header: dict[str, str] | None = None,
        stats: ProxyStats | None = None,
    ) -> None:
        self.dialect = dialect
        self.device = device
        self.transport = transport  # how the pcap shows the device link: "udp" or "tcp"
        self.pcap_path = Path(pcap) if pcap else None
        self.log_path = Path(log_path) if log_path else None
        self.log_header = dict(log_header or {})
        self.stats = stats if stats is not None else ProxyStats()
        self.subscribers: list[Subscriber] = []
        self._parsers: dict[tuple[str, str], FrameParser] = {}
        self._pcap: CaptureWriter | None = None
        self._log: BatchedTrafficLog | None = None
        # dialects a frame may be decoded by, by name (the preferred one keeps a model's options)
        self._dialects: dict[str, Dialect] = {dialect.name: dialect} if dialect else {}

    def open(self) -> None:
        try:
            if self.pcap_path:
                self._pcap = CaptureWriter(self.pcap_path, flush_each=False)
            if self.log_path:
                self._log = BatchedTrafficLog(self.log_path, **self.log_header)
        except OSError as exc:
            self.close()
            raise ProxyError(f"cannot write {exc.filename}: {exc.strerror}") from None

    @property
    def writes_files(self) -> bool:
        return self._pcap is not None or self._log is not None

    def subscribe(self, callback: Subscriber) -> Callable[[], None]:
        if len(self.subscribers) >= MAX_SUBSCRIBERS:
            raise ProxyError(f"at most {MAX_SUBSCRIBERS} subscribers")
        self.subscribers.append(callback)

        def unsubscribe() -> None:
            with contextlib.suppress(ValueError):
                self.subscribers.remove(callback)

        return unsubscribe

    # -- the work, in steps ---------------------------------------------------------------------

    def steps(self, chunk: Chunk) -> Iterator[bool]:
        """One chunk's work in steps (parse and capture, then per frame: decode and log, then each
        subscriber); the caller may forward waiting traffic between two steps."""
        t, client, endpoint, direction, data, from_datagram, items = chunk
        if direction == CLOSED:
            for d in (OUT, IN):
                self._parsers.pop((client, d), None)
            if self._pcap is not None and self.transport == "tcp":
                self._pcap.close_tcp(endpoint, self.device, t)
            return
        if items is None:
            parser = self._parsers.get((client, direction))
            if parser is None:
                parser = self._parsers[(client, direction)] = FrameParser()
            items = parser.feed_datagram(data) if from_datagram else parser.feed(data)
        if data:
            self._record(t, endpoint, direction, data)
        for item in items:
            if isinstance(item, Frame):
                if direction == OUT:
                    self.stats.frames_out += 1
                else:
                    self.stats.frames_in += 1
            if not self.subscribers and self._log is None:
                continue  # nobody reads the decoding (`proxy --quiet`): counting is all
            yield True
            event = self._event(t, client, direction, item)
            for callback in list(self.subscribers):
                yield True
                try:
                    callback(event)
                except Exception:
                    self.stats.subscriber_errors += 1
                    log.exception("proxy: subscriber %r failed", callback)

    def run(self, chunk: Chunk) -> None:
        """All of one chunk's work at once."""
        for _ in self.steps(chunk):
            pass

    def _record(self, t: float, endpoint: Endpoint, direction: str, data: bytes) -> None:
        if direction == OUT:
            self.stats.bytes_out += len(data)
        else:
            self.stats.bytes_in += len(data)
        if self._pcap is None:
            return
        a, b = (endpoint, self.device) if direction == OUT else (self.device, endpoint)
        try:
            if self.transport == "tcp":
                self._pcap.tcp(a, b, data, t, client=endpoint)
            else:
                self._pcap.udp(a, b, data, t)
        except (OSError, ValueError) as exc:
            self._lost("pcap", exc)

    def decode(self, frame: Frame) -> Message:
        """`decode_any` with the preferred dialect. It tries that dialect first anyway; asking it
        here first skips ranking the others when it decodes the frame (nearly always)."""
        if self.dialect is not None:
            msg = self.dialect.decode(frame)
            if msg.fields is not None:
                return msg
        return decode_any(frame, prefer=self.dialect)

    def _dialect_of(self, msg: Message) -> Dialect | None:
        if msg.dialect is None:
            return self.dialect
        d = self._dialects.get(msg.dialect)
        if d is None:
            d = self._dialects[msg.dialect] = get_dialect(msg.dialect)
        return d

    def _event(self, t: float, client: str, direction: str, item: Frame | Diagnostic) -> ProxyEvent:
        """A frame decoded once (the log and every subscriber reuse it), or a diagnostic."""
        dialect: Dialect | None = None
        message: Message | None = None
        if isinstance(item, Frame):
            message = self.decode(item)
            dialect = self._dialect_of(message)
            if self._log is not None:
                try:
                    self._log.record(direction, item, message)
                except OSError as exc:
                    self._lost("log", exc)
        return ProxyEvent(t, direction, client, item, dialect, message)

    # -- files ----------------------------------------------------------------------------------

    def flush(self) -> None:
        """Hand what the pcap and the log hold to their files."""
        self._files("flush")

    def close(self) -> None:
        """Write what waits and close the files."""
        self._files("close")
        self._pcap = self._log = None

    def _files(self, action: str) -> None:
        for which, writer in (("pcap", self._pcap), ("log", self._log)):
            if writer is not None:
                try:
                    getattr(writer, action)()
                except OSError as exc:
                    self._lost(which, exc)

    def _lost(self, which: str, exc: Exception) -> None:
        """Writing the pcap or the log failed: say so once and stop writing it (forwarding goes on)."""
        log.error(
            "proxy: %s %s: %s; no longer written", which, self.pcap_path if which == "pcap" else self.log_path, exc
        )
        if which == "pcap":
            self._pcap = None
        else:
            self._log = None
