"""TOP frames out of a capture file: packets -> conversations -> streams -> the frame parser.

A conversation is taken for TOP traffic when a user filter selects it, when it uses a documented
port (`ports.documented_ports()`), or once one of its payloads looks like TOP by the rule of
`heuristic.py` (the Wireshark dissector's heuristic applies the same rule, generated from it); other traffic in the file is passed over silently. UDP
payloads are parsed as whole datagrams, TCP payloads as a reassembled stream per direction.
Everything is bounded: at most `MAX_CONVERSATIONS` are tracked (the least recently active is
dropped, with a note), and each TCP direction buffers at most `tcpstream.MAX_PENDING` bytes.
"""

from __future__ import annotations

import ipaddress
from collections import OrderedDict
from collections.abc import Iterable, Iterator
from dataclasses import dataclass, field
from pathlib import Path

from ..protocol import Diagnostic, Frame, FrameParser
from .heuristic import looks_like_top
from .packets import TCP_FIN, TCP_RST, Endpoint, Segment, parse_packet
from .pcapfile import CaptureProblem, CaptureRecord, read_capture
from .ports import dialect_for_ports
from .tcpstream import TcpStream

MAX_CONVERSATIONS = 4096


@dataclass(frozen=True)
class WireFrame:
    """A frame (or what the parser says about bytes that are not one) seen in a capture."""

    ts: float
    number: int  # the packet that completed it (Wireshark's frame number)
    transport: str
    src: Endpoint
    dst: Endpoint
    item: Frame | Diagnostic
    dialect: str | None  # what a documented port says; None: decide by the frame


@dataclass(frozen=True)
class PacketNote:
    """A packet (or conversation) that could not be used, and why."""

    number: int
    ts: float
    detail: str


@dataclass
class _Direction:
    parser: FrameParser = field(default_factory=FrameParser)
    stream: TcpStream = field(default_factory=TcpStream)


@dataclass
class _Conversation:
    transport: str
    dialect: str | None
    top: bool
    ends: frozenset[Endpoint] = frozenset()  # both endpoints, also when only one has sent
    sides: dict[Endpoint, _Direction] = field(default_factory=dict)


class _Filter:
    def __init__(self, ports: Iterable[int], addresses: Iterable[str]) -> None:
        self.ports = frozenset(ports)
        self.addresses = frozenset(str(ipaddress.ip_address(a)) for a in addresses)

    @property
    def active(self) -> bool:
        return bool(self.ports or self.addresses)

    def __call__(self, seg: Segment) -> bool:
        if self.ports and seg.src[1] not in self.ports and seg.dst[1] not in self.ports:
            return False
        return not self.addresses or seg.src[0] in self.addresses or seg.dst[0] in self.addresses


def frames_in_capture(
    path: str | Path, *, ports: Iterable[int] = (), addresses: Iterable[str] = ()
) -> Iterator[WireFrame | PacketNote | CaptureProblem]:
    """Every TOP frame and parser diagnostic in a pcap/pcapng file, in packet order, with notes on
    packets that could not be used. `ports` / `addresses` keep only conversations with one of
    them on either side (and treat those as TOP whatever their ports). Raises CaptureError only
    when the file is not a capture at all."""
    keep = _Filter(ports, addresses)
    convs: OrderedDict[tuple[str, frozenset[Endpoint]], _Conversation] = OrderedDict()
    last_ts = 0.0
    last_number = 0
    for rec in read_capture(path):
        if isinstance(rec, CaptureProblem):
            yield rec
            continue
        last_ts, last_number = rec.ts, rec.number
        yield from _packet(rec, keep, convs)
    for conv in convs.values():
        yield from _finish(conv, last_ts, last_number)


def _packet(
    rec: CaptureRecord, keep: _Filter, convs: OrderedDict[tuple[str, frozenset[Endpoint]], _Conversation]
) -> Iterator[WireFrame | PacketNote]:
    seg = parse_packet(rec.linktype, rec.data)
    if seg is None:
        return
    if isinstance(seg, str):
        yield PacketNote(rec.number, rec.ts, seg)
        return
    if not keep(seg):
        return
    key = (seg.transport, frozenset((seg.src, seg.dst)))
    conv = convs.get(key)
    if conv is None:
        hint = dialect_for_ports(seg.transport, seg.src[1], seg.dst[1])
        conv = _Conversation(seg.transport, hint, keep.active or hint is not None, key[1])
        convs[key] = conv
        if len(convs) > MAX_CONVERSATIONS:
            _, old = convs.popitem(last=False)
            yield PacketNote(rec.number, rec.ts, f"more than {MAX_CONVERSATIONS} conversations: the oldest is closed")
            yield from _finish(old, rec.ts, rec.number)
    else:
        convs.move_to_end(key)
    if not conv.top and seg.payload:
        conv.top = looks_like_top(seg.payload)
    if not conv.top:
        return
    side = conv.sides.setdefault(seg.src, _Direction())

    def out(items: list[Frame | Diagnostic]) -> Iterator[WireFrame]:
        for item in items:
            yield WireFrame(rec.ts, rec.number, seg.transport, seg.src, seg.dst, item, conv.dialect)

    if seg.transport == "udp":
        yield from out(side.parser.feed_datagram(seg.payload))
        return
    for piece in side.stream.add(seg.seq, seg.flags, seg.payload):
        if piece.gap:
            yield from out(side.parser.flush())
            yield PacketNote(rec.number, rec.ts, f"TCP {_ep(seg.src)} -> {_ep(seg.dst)}: {piece.gap} bytes missing")
        yield from out(side.parser.feed(piece.data))
    if seg.flags & (TCP_FIN | TCP_RST):
        yield from out(side.parser.flush())


def _finish(conv: _Conversation, ts: float, number: int) -> Iterator[WireFrame | PacketNote]:
    """End of the file: bytes still waiting in TCP streams and parsers."""
    if not conv.top:
        return
    for src, side in conv.sides.items():
        dst = next((e for e in conv.ends if e != src), src)
        items: list[Frame | Diagnostic] = []
        for piece in side.stream.finish():
            if piece.gap:
                items += side.parser.flush()
                yield PacketNote(number, ts, f"TCP {_ep(src)} -> {_ep(dst)}: {piece.gap} bytes missing")
            items += side.parser.feed(piece.data)
        items += side.parser.flush()
        for item in items:
            yield WireFrame(ts, number, conv.transport, src, dst, item, conv.dialect)


def _ep(ep: Endpoint) -> str:
    return f"[{ep[0]}]:{ep[1]}" if ":" in ep[0] else f"{ep[0]}:{ep[1]}"
