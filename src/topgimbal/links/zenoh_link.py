"""A MAVLink link onto a Zenoh session, in BlueOS mavlink-server's key shape (json_shape.py).

Every frame the node sends is published as JSON on `mavlink/out`, on
`mavlink/{system_id}/{component_id}/{MESSAGE}` and, one entry each, on
`mavlink/{system_id}/{component_id}/{MESSAGE}/{field}` (the `type` entry too), as mavlink-server's
Zenoh driver does. JSON put on `mavlink/in` is decoded, encoded as a MAVLink frame from the
header's system and component, and handed to the node like bytes from any peer ("zenoh").
Bad input (not JSON, more than MAX_IN_BYTES, unknown message, wrong field) is dropped and counted
in `bad_in`, with a warning at most every 10 s; so is input beyond MAX_PENDING_IN samples waiting
for the event loop (`dropped_in`).

The session is the caller's (the fleet server's); this link opens and closes none. Zenoh calls
back on its own threads: samples are handed to the event loop the link was started on."""

from __future__ import annotations

import asyncio
import contextlib
import logging
import threading
from typing import Any

from ..logthrottle import ThrottledLog
from . import json_shape
from .base import DataCallback, EndpointSpec, GoneCallback, Link
from .mav import mavlink

log = logging.getLogger("topgimbal.mavlink")

PREFIX = "mavlink"
PEER = "zenoh"
MAX_PUBLISHERS = 4096  # declared keys kept; a few components x messages x fields stays far below
MAX_PENDING_IN = 256  # mavlink/in samples waiting for the event loop; a flood beyond is dropped


class ZenohLink(Link):
    def __init__(self, session: Any, on_data: DataCallback, on_gone: GoneCallback, max_peers: int = 1) -> None:
        super().__init__(EndpointSpec("zenoh", text=f"zenoh:{PREFIX}/**"), on_data, on_gone, max_peers)
        self.session = session
        self.published = 0
        self.bad_in = 0
        self.dropped_in = 0  # a flood: more than MAX_PENDING_IN waiting
        self._publishers: dict[str, Any] = {}
        self._subscriber: Any = None
        self._loop: asyncio.AbstractEventLoop | None = None
        self._parser = mavlink().MAVLink(None)
        self._parser.robust_parsing = True
        self._bad_log = ThrottledLog(log, 10.0)
        self._pending = 0
        self._pending_lock = threading.Lock()

    @property
    def peer_count(self) -> int:
        return 1

    async def start(self) -> None:
        self._loop = asyncio.get_running_loop()
        self._subscriber = self.session.declare_subscriber(f"{PREFIX}/in", self._on_sample)

    def _on_sample(self, sample: Any) -> None:  # a Zenoh thread
        loop = self._loop
        if loop is None or self._closed:
            return
        with self._pending_lock:
            if self._pending >= MAX_PENDING_IN:
                self.dropped_in += 1
                return
            self._pending += 1
        try:
            data = bytes(sample.payload.to_bytes())
        except Exception:  # a payload Zenoh cannot hand over: nothing to decode
            data = b"\xff"
        try:
            loop.call_soon_threadsafe(self._received, data)
        except RuntimeError:  # the loop closed meanwhile
            pass

    def _received(self, data: bytes) -> None:
        with self._pending_lock:
            self._pending -= 1
        if self.dropped_in and self._bad_log.allow("flood") is not None:
            log.warning("%s/in: %d messages dropped in all: more than %d waiting", PREFIX, self.dropped_in,
                        MAX_PENDING_IN)  # fmt: skip
        try:
            header, msg = json_shape.loads(data)
            frame = json_shape.encode(header, msg)
        except Exception as exc:  # ShapeError; anything else the shape check missed is dropped the same way
            if not isinstance(exc, json_shape.ShapeError):
                exc = json_shape.ShapeError(f"{type(exc).__name__}: {exc}"[:300])
            self.bad_in += 1
            n = self._bad_log.allow("bad")
            if n is not None:
                log.warning("%s/in: dropped a message (%s; %d dropped in all)", PREFIX, exc, self.bad_in)
            return
        self._deliver(PEER, frame)

    def send(self, data: bytes) -> None:
        if self._closed:
            self.dropped_out += 1
            return
        try:
            msgs = self._parser.parse_buffer(data) or []
        except Exception:  # our own frames; be sure all the same
            self.dropped_out += 1
            return
        for m in msgs:
            if m.get_type() == "BAD_DATA":
                continue
            obj = json_shape.to_obj(m)
            text = json_shape.dumps(obj)
            base = f"{PREFIX}/{m.get_srcSystem()}/{m.get_srcComponent()}/{m.get_type()}"
            self._put(f"{PREFIX}/out", text)
            self._put(base, text)
            for field, value in json_shape.field_payloads(obj["message"]):
                self._put(f"{base}/{field}", value)
            self.published += 1
            self.bytes_out += len(text)

    def _put(self, key: str, text: str) -> None:
        pub = self._publishers.get(key)
        try:
            if pub is None:
                if len(self._publishers) >= MAX_PUBLISHERS:
                    self.session.put(key, text, encoding=_json_encoding())
                    return
                pub = self._publishers[key] = self.session.declare_publisher(key, encoding=_json_encoding())
            pub.put(text)
        except Exception as exc:  # a closing session: the message is lost, the bridge goes on
            self.dropped_out += 1
            log.debug("%s: put failed: %s", key, exc)

    async def close(self) -> None:
        self._closed = True
        for d in [self._subscriber, *self._publishers.values()]:
            if d is not None:
                with contextlib.suppress(Exception):
                    d.undeclare()
        self._subscriber = None
        self._publishers.clear()
        self._on_gone(self, PEER)


def _json_encoding() -> Any:
    import zenoh  # there is a session, so eclipse-zenoh is installed

    return zenoh.Encoding.APPLICATION_JSON


def zenoh_link_factory(session: Any) -> Any:
    """What `Node(..., link_factories=[...])` takes: the link made with the node's callbacks."""

    def make(on_data: DataCallback, on_gone: GoneCallback) -> Link:
        return ZenohLink(session, on_data, on_gone)

    return make


__all__ = ["MAX_PUBLISHERS", "PEER", "PREFIX", "ZenohLink", "zenoh_link_factory"]
