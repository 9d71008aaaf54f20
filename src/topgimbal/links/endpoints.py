"""MAVLink links in pymavlink's connection-string syntax, on asyncio.

    udpin:HOST:PORT    listen; answer every peer heard in the last PEER_TIMEOUT_S (at most max_peers)
    udp:HOST:PORT      the same as udpin (as in pymavlink)
    udpout:HOST:PORT   send to HOST:PORT, take what comes back
    tcp:HOST:PORT      connect; reconnect with back-off when the peer goes away
    tcpin:HOST:PORT    listen; at most max_peers connections at once; one silent for PEER_TIMEOUT_S
                       is closed when a new one needs its place (or when we next send)
    DEVICE[,BAUD]      a serial port (/dev/ttyUSB0,57600; default 115200); reopened when it fails
    memory:NAME        in-process (tests, embedding): peers connect by NAME (memory_link.py)

Links carry bytes only; the node parses MAVLink per (link, peer) so a stream split anywhere is
reassembled. Every buffer is bounded: peers per link, bytes queued per connection
(base.py: the string and the base class; udp_link.py, stream_link.py, memory_link.py: the kinds.)"""

from __future__ import annotations

from .base import (
    DEFAULT_BAUD,
    FORMS,
    LINK_KINDS,
    MAX_PEERS,
    PEER_TIMEOUT_S,
    DataCallback,
    EndpointError,
    EndpointSpec,
    GoneCallback,
    Link,
    parse_endpoint,
)
from .stream_link import StreamLink
from .udp_link import UdpLink

__all__ = [
    "DEFAULT_BAUD",
    "FORMS",
    "MAX_PEERS",
    "PEER_TIMEOUT_S",
    "DataCallback",
    "EndpointError",
    "EndpointSpec",
    "GoneCallback",
    "Link",
    "StreamLink",
    "UdpLink",
    "make_link",
    "parse_endpoint",
]


def make_link(
    spec: EndpointSpec | str, on_data: DataCallback, on_gone: GoneCallback, max_peers: int = MAX_PEERS
) -> Link:
    spec = parse_endpoint(spec) if isinstance(spec, str) else spec
    if spec.kind in LINK_KINDS:
        return LINK_KINDS[spec.kind](spec, on_data, on_gone, max_peers)
    cls: type[Link] = UdpLink if spec.kind in ("udpin", "udpout") else StreamLink
    return cls(spec, on_data, on_gone, max_peers)
