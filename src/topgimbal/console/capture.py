"""What the console saw on the wire, kept for a pcap download (`GET /api/traffic.pcap`).

The recorder keeps the most recent frames, in and out, with their wall-clock time: at most
`MAX_FRAMES` frames and `MAX_BYTES` bytes of frame data, the oldest forgotten first (a 50 Hz attitude
stream fills it in about three minutes). `pcap()` writes them through `topgimbal.wire.CaptureWriter`
as packets between the console and the camera, so the file opens in Wireshark and tshark with the
generated dissector (`topgimbal dissector`).

Addresses in the file: the camera's side is its URL's address when that is an IP address (else the
loopback address) and its port; the console's side is the loopback address of the same family and
the documented client port of the dialect when it has one (TOPOTEK UDP 9004, so the dissector picks
the dialect), else `HOST_PORT`. The console's real ephemeral port is not known to the client API.
A serial camera is shown as UDP on the model's first documented UDP port. In `--proxy` mode each
frame keeps the proxy client's own address.
"""

from __future__ import annotations

import ipaddress
import tempfile
from collections import deque
from collections.abc import Iterable
from dataclasses import dataclass
from pathlib import Path

from ..protocol import DeviceModel
from ..transport import network_address
from ..wire import CaptureWriter
from ..wire.packets import Endpoint
from ..wire.ports import client_port

MAX_FRAMES = 10_000
MAX_BYTES = 2 * 1024 * 1024
HOST_PORT = 40000  # the console's side in a pcap, when the dialect documents no client port


@dataclass(frozen=True)
class Recorded:
    t: float  # wall clock, seconds
    direction: str  # "out": console (or proxy client) -> camera; "in": camera -> console
    data: bytes  # the frame as on the wire
    host: Endpoint | None = None  # the other end when known (a proxy's client)


@dataclass(frozen=True)
class Link:
    """How the console reaches the camera, as the pcap shows it."""

    transport: str  # "udp" or "tcp"
    host: Endpoint
    device: Endpoint


class Recorder:
    """The newest frames, bounded in count and bytes."""

    def __init__(self, max_frames: int = MAX_FRAMES, max_bytes: int = MAX_BYTES) -> None:
        self.max_frames = max_frames
        self.max_bytes = max_bytes
        self._frames: deque[Recorded] = deque()
        self._bytes = 0
        self.total = 0  # frames ever recorded
        self.forgotten = 0  # frames dropped to stay within the bounds

    def add(self, t: float, direction: str, data: bytes, host: Endpoint | None = None) -> None:
        self._frames.append(Recorded(t, direction, bytes(data), host))
        self._bytes += len(data)
        self.total += 1
        while len(self._frames) > self.max_frames or (self._bytes > self.max_bytes and len(self._frames) > 1):
            old = self._frames.popleft()
            self._bytes -= len(old.data)
            self.forgotten += 1

    def clear(self) -> None:
        self._frames.clear()
        self._bytes = 0

    def __len__(self) -> int:
        return len(self._frames)

    @property
    def bytes(self) -> int:
        return self._bytes

    def frames(self) -> list[Recorded]:
        return list(self._frames)

    def describe(self) -> dict[str, int]:
        return {
            "frames": len(self._frames),
            "bytes": self._bytes,
            "total": self.total,
            "forgotten": self.forgotten,
            "max_frames": self.max_frames,
            "max_bytes": self.max_bytes,
        }


def _loopback_for(host: str) -> tuple[str, str]:
    """(the address to show for `host`, the loopback address of its family)."""
    try:
        ip = ipaddress.ip_address(host.strip("[]"))
    except ValueError:
        return "127.0.0.1", "127.0.0.1"
    return str(ip), "::1" if ip.version == 6 else "127.0.0.1"


def link_for(url: str, model: DeviceModel) -> Link:
    """The console's link to the camera at `url` as the pcap shows it (see the module text)."""
    address = network_address(url)
    if address is not None:
        transport, host, port = address
        device_ip, loopback = _loopback_for(host)
    else:
        documented = [e.port for e in model.endpoints if e.kind == "udp" and e.port is not None]
        transport, port, device_ip, loopback = "udp", (documented or [5000])[0], "127.0.0.1", "127.0.0.1"
    return Link(transport, (loopback, client_port(transport, model.dialect, HOST_PORT)), (device_ip, port))


def pcap(frames: Iterable[Recorded], link: Link) -> bytes:
    """The frames as a pcap file (bytes): one datagram or TCP segment per frame, at its time."""
    with tempfile.TemporaryDirectory(prefix="topgimbal-console-") as tmp:
        path = Path(tmp) / "traffic.pcap"
        with CaptureWriter(path) as out:
            for r in frames:
                host = r.host or link.host
                src, dst = (host, link.device) if r.direction == "out" else (link.device, host)
                if link.transport == "tcp":
                    out.tcp(src, dst, r.data, r.t, client=host)
                else:
                    out.udp(src, dst, r.data, r.t)
        return path.read_bytes()
