"""Thin asyncio transports around the device: UDP, TCP and serial (a device path or a fresh pty).

Each server turns what arrives into `sink(peer, data, datagram)` calls and gives every remote end a
peer object with `send(data)`. Nothing here knows the protocol.

Every resource a remote end can make the server hold is bounded (`Limits`, docs/simulator.md
"Limits"): UDP peers (LRU-evicted at the cap, forgotten on ICMP "port unreachable" or after a lease
without a datagram), TCP clients (refused at the cap) and each TCP client's unsent bytes (a client
that does not read is dropped at the high-water mark). A UDP send that would block is dropped, as a
congested link drops it: nothing is ever queued in user space for UDP.
"""

from typing import TYPE_CHECKING

from ..._lazy import lazy_getattr
from .common import LOOPBACK, Limits, ListenError, Throttled, listen_error

if TYPE_CHECKING:
    from .serial import SerialPeer, configure_tty
    from .tcp import TcpPeer, TcpServer
    from .udp import UdpPeer, UdpServer

# The asyncio servers load on first use (PEP 562): `Limits` alone (the CLI's defaults) stays light.
_LAZY = {
    "SerialPeer": "serial", "configure_tty": "serial", "TcpPeer": "tcp", "TcpServer": "tcp", "UdpPeer": "udp",
    "UdpServer": "udp",
}  # fmt: skip


__getattr__ = lazy_getattr(__name__, _LAZY, globals())


__all__ = [
    "LOOPBACK",
    "Limits",
    "ListenError",
    "SerialPeer",
    "TcpPeer",
    "TcpServer",
    "Throttled",
    "UdpPeer",
    "UdpServer",
    "configure_tty",
    "listen_error",
]
