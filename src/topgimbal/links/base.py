"""What every MAVLink link shares: the connection string (`parse_endpoint`, `EndpointSpec`), the
bounds, and `Link`, the base a kind of link builds on (udp_link.py, stream_link.py, memory_link.py;
endpoints.py makes one from a string). A link carries bytes only; the node parses MAVLink per
(link, peer) so a stream split anywhere is reassembled. Every buffer is bounded: peers per link,
bytes queued per connection."""

from __future__ import annotations

import abc
import logging
import re
from collections.abc import Callable, Hashable
from dataclasses import dataclass
from typing import Any

from ..errors import TopGimbalError
from ..logthrottle import ThrottledLog
from ..peers import REFUSE, Gone, PeerTable, Words

log = logging.getLogger("topgimbal.mavlink")

MAX_PEERS = 16
PEER_TIMEOUT_S = 30.0
MAX_WRITE_BUFFER = 256 * 1024
# tcpin with a signing key: bytes a connection may send with nothing signed among them before it is
# closed (a MAVLink 2 signed frame is at most 280 bytes; a few unsigned heartbeats pass under it)
MAX_UNTRUSTED_BYTES = 4096
# The peer table's refusal line (peers.py; throttled, one per 10 s, the next one counting the rest).
WORDS = Words(refused="{name}: already {cap} peers (the limit); ignoring {newcomer}")
RECONNECT_MIN_S = 0.5
RECONNECT_MAX_S = 5.0
DEFAULT_BAUD = 115200

# Returns False when nothing in the bytes was accepted (a signing key is set and none was signed
# with it): a UDP sender is then no peer. None or True: accepted.
DataCallback = Callable[["Link", Hashable, bytes], "bool | None"]
GoneCallback = Callable[["Link", Hashable], None]


# Which link and peer a message came from, tagged on the message by the node that received it (the
# message object is pymavlink's, so an attribute of ours): commands remember it for their fairness
# bounds, FTP for its sessions, the reboot watch for connections that closed.
_PEER_ATTR = "_topgimbal_link_peer"


def tag_peer(m: Any, link: object, peer: Hashable) -> None:
    setattr(m, _PEER_ATTR, (str(link), peer))


def link_peer(m: Any) -> Hashable | None:
    """Where a message came from: (link, peer address or connection) as the node saw it; None
    for a message that did not come through a node (tests that feed a dispatcher directly)."""
    peer: Hashable | None = getattr(m, _PEER_ATTR, None)
    return peer


class EndpointError(TopGimbalError, ValueError):
    """A MAVLink connection string that cannot be used."""


@dataclass(frozen=True)
class EndpointSpec:
    kind: str  # udpin, udpout, tcp, tcpin, serial, memory (NAME in device)
    host: str = ""
    port: int = 0
    device: str = ""
    baud: int = DEFAULT_BAUD
    text: str = ""

    def __str__(self) -> str:
        return self.text


FORMS = "udpin:HOST:PORT, udpout:HOST:PORT, tcp:HOST:PORT, tcpin:HOST:PORT, a serial DEVICE[,BAUD] or memory:NAME"
MEMORY_NAME = re.compile(r"[A-Za-z0-9][A-Za-z0-9._-]{0,63}")
# Link kinds whose module builds on this one (memory_link.py registers "memory" when imported, as
# node.py does): made here all the same, without an import circle.
LINK_KINDS: dict[str, Callable[[EndpointSpec, DataCallback, GoneCallback, int], Link]] = {}


def parse_endpoint(text: str) -> EndpointSpec:
    """Parse one pymavlink-style connection string; EndpointError says what is allowed."""
    if not isinstance(text, str) or not text.strip():
        raise EndpointError(f"empty MAVLink endpoint: expected {FORMS}")
    s = text.strip()
    scheme, sep, rest = s.partition(":")
    scheme = scheme.lower()
    if sep and scheme in ("udp", "udpin", "udpout", "tcp", "tcpin"):
        host, _, port_text = rest.rpartition(":")
        host = host.strip("[]")
        if not host or not port_text.isdigit() or not 0 <= int(port_text) <= 65535:
            raise EndpointError(f"{text!r}: expected {scheme}:HOST:PORT (port 0..65535)")
        port = int(port_text)
        kind = "udpin" if scheme == "udp" else scheme
        if kind in ("udpout", "tcp") and port == 0:
            raise EndpointError(f"{text!r}: {kind} needs the peer's port, not 0")
        return EndpointSpec(kind, host, port, text=s)
    if sep and scheme == "memory":
        if not MEMORY_NAME.fullmatch(rest):
            raise EndpointError(f"{text!r}: expected memory:NAME (1..64 letters, digits, '.', '_', '-'; "
                                "a letter or digit first)")  # fmt: skip
        return EndpointSpec("memory", device=rest, text=s)
    if scheme in ("udpbcast", "mcast", "wsserver", "ws", "wss"):
        raise EndpointError(f"{text!r}: {scheme}: links are not supported; use {FORMS}")
    device, baud = s, DEFAULT_BAUD
    for sep_char in (",", "@"):
        if sep_char in s:
            device, _, baud_text = s.rpartition(sep_char)
            if not baud_text.isdigit():
                raise EndpointError(f"{text!r}: baud {baud_text!r} is not a number")
            baud = int(baud_text)
            break
    if not (device.startswith("/") or device.upper().startswith("COM")):
        raise EndpointError(f"{text!r}: not a MAVLink endpoint; expected {FORMS}")
    return EndpointSpec("serial", device=device, baud=baud, text=s)


class Link(abc.ABC):
    """One MAVLink link: bytes in through `on_data(link, peer, data)`, `send()` to every peer."""

    def __init__(self, spec: EndpointSpec, on_data: DataCallback, on_gone: GoneCallback, max_peers: int) -> None:
        self.spec = spec
        self._on_data = on_data
        self._on_gone = on_gone
        self.max_peers = max_peers
        self.bytes_in = 0
        self.bytes_out = 0
        self.dropped_out = 0
        self.untrusted_closed = 0  # tcpin with a signing key: connections closed for sending nothing signed
        # Set by a node with a signing key: a listening link then serves only senders whose bytes
        # it accepted (udpin: no peer place, tcpin: no telemetry, closed after MAX_UNTRUSTED_BYTES).
        self.needs_trust = False
        self._closed = False
        self._refusal_log = ThrottledLog(log, 10.0)  # a peer flood: one line per 10 s
        # The shared peer table (peers.py): at most max_peers, a newcomer refused at the cap; on a
        # listening link one silent for PEER_TIMEOUT_S gives its place back (udpin: forgotten,
        # tcpin: closed). Values: udpin the address, streams their connection.
        listening = spec.kind in ("udpin", "tcpin", "memory")
        self.peers: PeerTable[Hashable, Any] = PeerTable(
            max_peers,
            at_cap=REFUSE,
            lease_s=PEER_TIMEOUT_S if listening else 0.0,
            name=spec.text,
            throttle=self._refusal_log,
            words=WORDS,
            on_gone=self._gone,
        )

    @property
    def refused_peers(self) -> int:
        """Peers turned away: at the cap, or (tcpin with a signing key) for sending nothing signed."""
        return self.peers.refused + self.untrusted_closed

    def _gone(self, gone: Gone[Hashable, Any]) -> None:
        """A peer left the table (silent for the lease, closed, or untrusted): the node forgets it."""
        self._on_gone(self, gone.key)

    def __str__(self) -> str:
        return self.spec.text

    @property
    def address(self) -> tuple[str, int] | None:
        """The local (host, port) a listening link is bound to (port 0 resolved)."""
        return None

    @property
    @abc.abstractmethod
    def peer_count(self) -> int: ...

    @abc.abstractmethod
    async def start(self) -> None: ...

    @abc.abstractmethod
    def send(self, data: bytes) -> None: ...

    @abc.abstractmethod
    async def close(self) -> None: ...

    def send_to(self, peer: Hashable, data: bytes) -> None:
        """To one peer (a reply only it asked for); links that cannot address one send to all."""
        self.send(data)

    def _deliver(self, peer: Hashable, data: bytes) -> bool:
        """Whether the node accepted anything in `data` (see DataCallback)."""
        self.bytes_in += len(data)
        try:
            return self._on_data(self, peer, data) is not False
        except Exception:  # one bad packet must not end the link
            log.exception("%s: handling %d bytes from %s failed", self, len(data), peer)
            return False
