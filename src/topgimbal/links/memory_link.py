"""`memory:NAME`: an in-process MAVLink link, for tests and for embedding the bridge next to a
ground station or an autopilot written in Python. No socket, no thread.

    bridge = Bridge(BridgeConfig(url="memory://cam", model="C12", endpoints=["memory:gcs"],
                                 definition_http=None))
    await bridge.start()
    gcs = connect_memory("gcs", on_bytes=handle)     # the other end, by name
    gcs.send(heartbeat.pack(mav))

The node's side listens like udpin: each end that connects is a peer (its own MAVLink parser,
replies addressed to it); the ends connect by NAME. Every send is one chunk handed over through the
event loop (`call_soon`), as a network would, so a virtual-time loop (looptime) drives it: with the
simulator on `memory://` and this link, a whole rig runs without real waiting.

Bounded like the other links: at most MAX_LINKS names in the process (a name in use or the table
full: EndpointError), `max_peers` ends per link (one more: EndpointError, a throttled log line, and
an end silent for PEER_TIMEOUT_S gives its place first, as on tcpin), and at most MAX_QUEUED_BYTES
handed over but not yet delivered per end and direction (more is dropped and counted, as a peer
that does not read loses messages on TCP)."""

from __future__ import annotations

import asyncio
import logging
from collections.abc import Callable, Hashable
from typing import Any

from ..peers import EXPIRED, Gone
from . import base
from .base import EndpointError, EndpointSpec, Link

log = logging.getLogger("topgimbal.mavlink")

MAX_LINKS = 256  # memory: names open at once in one process
MAX_QUEUED_BYTES = 256 * 1024  # per end and direction, handed over but not yet delivered

_LINKS: dict[str, MemoryLink] = {}

BytesCallback = Callable[[bytes], None]


class _Pipe:
    """One direction of one end: chunks handed to the loop, at most MAX_QUEUED_BYTES in flight."""

    def __init__(self, loop: asyncio.AbstractEventLoop, sink: BytesCallback) -> None:
        self.loop = loop
        self.sink = sink
        self.pending = 0
        self.dropped = 0

    def put(self, data: bytes) -> bool:
        if self.pending + len(data) > MAX_QUEUED_BYTES:
            self.dropped += 1
            return False
        self.pending += len(data)
        self.loop.call_soon(self._arrive, bytes(data))
        return True

    def _arrive(self, data: bytes) -> None:
        self.pending -= len(data)
        self.sink(data)


class MemoryPeer:
    """The other end of `memory:NAME` (a ground station, an autopilot, a test): `send(bytes)` to
    the node; what the node sends comes to `on_bytes`. Made by `connect_memory`."""

    def __init__(self, link: MemoryLink, on_bytes: BytesCallback | None) -> None:
        self.link = link
        self.on_bytes = on_bytes
        self.on_close: Callable[[], None] | None = None  # the link closed (the bridge stopped)
        self.closed = False
        self.trusted = False  # the node accepted something it sent (matters with a signing key)
        self.bytes_in = 0  # from the node
        self.bytes_out = 0  # to the node
        loop = link.loop
        assert loop is not None  # a started link
        self._to_node = _Pipe(loop, self._arrive_at_node)
        self._to_peer = _Pipe(loop, self._arrive_here)
        self.peer: Hashable = None  # the node's name for this end, given when it is let in
        self.peer = link._attach(self)

    @property
    def dropped(self) -> int:
        """Chunks not delivered because MAX_QUEUED_BYTES were in flight (both directions)."""
        return self._to_node.dropped + self._to_peer.dropped

    def send(self, data: bytes) -> bool:
        """To the node; False when closed or the queue is full (the chunk is dropped)."""
        if self.closed:
            return False
        if not self._to_node.put(data):
            return False
        self.bytes_out += len(data)
        return True

    def close(self) -> None:
        """Leave the link (the node forgets this peer, as when a TCP connection closes)."""
        if self.closed:
            return
        self.closed = True
        self.link._detach(self)

    def _arrive_at_node(self, data: bytes) -> None:
        if not self.closed:
            self.link._from_end(self, data)

    def _arrive_here(self, data: bytes) -> None:
        if self.closed:
            return
        self.bytes_in += len(data)
        if self.on_bytes is not None:
            self.on_bytes(data)

    def _link_closed(self) -> None:
        self.closed = True
        if self.on_close is not None:
            self.on_close()

    def __repr__(self) -> str:
        return f"<memory:{self.link.name} end {self.peer or 'refused'}>"


def connect_memory(name: str, on_bytes: BytesCallback | None = None) -> MemoryPeer:
    """Connect to the started link `memory:NAME`; EndpointError when there is none or it is full."""
    link = _LINKS.get(name)
    if link is None:
        raise EndpointError(f"memory:{name}: no such MAVLink link (start a node or bridge on it first)")
    return MemoryPeer(link, on_bytes)


class MemoryLink(Link):
    """The node's side of `memory:NAME`: listens for ends, answers each like a udpin peer. Its ends
    are in the link's peer table (peers.py: at most max_peers, a newcomer refused at the cap, one
    silent for PEER_TIMEOUT_S gives its place back, as on tcpin)."""

    def __init__(self, spec: EndpointSpec, *a: Any, **kw: Any) -> None:
        super().__init__(spec, *a, **kw)
        self.name = spec.device  # checked by parse_endpoint (base.MEMORY_NAME)
        self.loop: asyncio.AbstractEventLoop | None = None
        self._serial_n = 0

    @property
    def peer_count(self) -> int:
        return len(self.peers)

    async def start(self) -> None:
        if self.name in _LINKS:
            raise EndpointError(f"{self.spec}: the name {self.name!r} is in use (one link per name)")
        if len(_LINKS) >= MAX_LINKS:
            raise EndpointError(f"{self.spec}: {MAX_LINKS} memory links are open in this process (the limit)")
        self.loop = asyncio.get_running_loop()
        self._closed = False
        _LINKS[self.name] = self

    def _attach(self, end: MemoryPeer) -> Hashable:
        self._serial_n += 1
        peer = ("memory", self._serial_n)
        if not self.peers.admit(peer, end):  # refused at the cap (counted and logged by the table)
            raise EndpointError(f"{self.spec}: already {self.max_peers} peers (the limit)")
        log.info("%s: connected (%s)", self, peer)
        return peer

    def _gone(self, gone: Gone[Hashable, Any]) -> None:
        if gone.why == EXPIRED:  # silent for the lease: its place goes to a newcomer
            log.info("%s: %s silent for %.0f s, closed", self, gone.key, self.peers.lease_s)
            gone.value._link_closed()
        super()._gone(gone)

    def _detach(self, end: MemoryPeer) -> None:
        if self.peers.get(end.peer) is end:
            log.info("%s: %s closed", self, end.peer)
            self.peers.forget(end.peer, end)

    def _from_end(self, end: MemoryPeer, data: bytes) -> None:
        if self._closed or self.peers.get(end.peer) is not end:
            return
        self.peers.heard(end.peer)
        if self._deliver(end.peer, data):
            end.trusted = True

    def _serves(self, end: MemoryPeer) -> bool:
        # with a signing key, an end hears nothing until it sent something signed (udpin's rule)
        return end.trusted or not self.needs_trust

    def _push(self, end: MemoryPeer, data: bytes) -> None:
        if end._to_peer.put(data):
            self.bytes_out += len(data)
        else:
            self.dropped_out += 1

    def send(self, data: bytes) -> None:
        ends = [e for e in self.peers.values() if self._serves(e)]
        if not ends:
            self.dropped_out += 1
            return
        for end in ends:
            self._push(end, data)

    def send_to(self, peer: Hashable, data: bytes) -> None:
        end = self.peers.get(peer)
        if end is None or not self._serves(end):
            self.dropped_out += 1
            return
        self._push(end, data)

    async def close(self) -> None:
        self._closed = True
        if _LINKS.get(self.name) is self:
            del _LINKS[self.name]
        for end in self.peers.clear():
            end._link_closed()


base.LINK_KINDS["memory"] = MemoryLink  # make_link("memory:NAME", ...) builds one
