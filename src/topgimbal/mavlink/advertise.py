"""The address written into the camera-definition URI (CAMERA_INFORMATION.cam_definition_uri).

A server bound to all interfaces (`--definition-http 0.0.0.0:PORT`) has no one address to give;
`127.0.0.1` (what it used to say) is useless to a ground station on another computer. So, unless
`--definition-host HOST` says what to write, the URI carries the address of the interface that
reaches the peer asking: the local address the kernel picks for a UDP socket `connect()`ed to that
peer (`getsockname()`; connecting a UDP socket sends no packet). A peer without an IP address (a
serial link, a request routed through the autopilot) falls back to the interface that reaches the
hosts the bridge's links point at, then to the one the default route uses, then to loopback."""

from __future__ import annotations

import contextlib
import ipaddress
import socket
from collections import OrderedDict
from collections.abc import Hashable, Sequence

ALL_INTERFACES = ("0.0.0.0", "", "::")
MAX_REMEMBERED = 64  # peer host -> local address, least recently used goes
# Any address outside this machine reaches the default route's interface; TEST-NET-1 (RFC 5737)
# is never a real host, and a UDP connect() sends nothing to it.
DEFAULT_ROUTE_PROBE = "192.0.2.1"


def reaching_address(peer_host: str) -> str | None:
    """The local address that reaches `peer_host` (an IP address), or None when none does."""
    try:
        family = socket.AF_INET6 if ipaddress.ip_address(peer_host).version == 6 else socket.AF_INET
    except ValueError:
        return None
    try:
        with socket.socket(family, socket.SOCK_DGRAM) as s:
            s.connect((peer_host, 9))  # no packet: a UDP connect only picks the route
            local = s.getsockname()[0]
    except OSError:
        return None
    return str(local) if local not in ALL_INTERFACES else None


def peer_host(where: Hashable | None) -> str | None:
    """The IP address in a message's `(link, peer)` (node.link_peer) when the peer has one."""
    if isinstance(where, tuple) and len(where) == 2:
        peer = where[1]
        if isinstance(peer, tuple) and peer and isinstance(peer[0], str):
            with contextlib.suppress(ValueError):
                return str(ipaddress.ip_address(peer[0].split("%", 1)[0]))
    return None


class Advertiser:
    """What host to write into a URI for a request from `where`."""

    def __init__(self, bind_host: str, given_host: str | None, link_hosts: Sequence[str]) -> None:
        self.bind_host = bind_host
        self.given_host = given_host
        self.link_hosts = [h for h in link_hosts if h and h not in ALL_INTERFACES]
        self._cache: OrderedDict[str | None, str] = OrderedDict()

    @property
    def fixed(self) -> str | None:
        """The host when it does not depend on the peer (given, or a specific bind address)."""
        if self.given_host:
            return self.given_host
        return None if self.bind_host in ALL_INTERFACES else self.bind_host

    def host_for(self, where: Hashable | None) -> str:
        fixed = self.fixed
        if fixed is not None:
            return fixed
        key = peer_host(where)
        got = self._cache.get(key)
        if got is None:
            got = self._find(key)
            self._cache[key] = got
            while len(self._cache) > MAX_REMEMBERED:
                self._cache.popitem(last=False)
        self._cache.move_to_end(key)
        return got

    def _find(self, host: str | None) -> str:
        for candidate in ([host] if host else []) + self.link_hosts + [DEFAULT_ROUTE_PROBE]:
            local = reaching_address(candidate)
            if local is not None:
                return local
        return "127.0.0.1"
