"""From packets to frames: TCP reassembly (order, retransmission, holes), frames split at every
byte, conversations picked by port, filter or heuristic."""

from __future__ import annotations

import random

import pytest

from topgimbal.protocol import Diagnostic, Frame
from topgimbal.wire import CaptureWriter, PcapWriter, tcpstream
from topgimbal.wire.capture import PacketNote, WireFrame, frames_in_capture
from topgimbal.wire.packets import TCP_ACK, TCP_PSH, TCP_SYN, build_packet
from topgimbal.wire.tcpstream import TcpStream

pytestmark = pytest.mark.loopback

HOST, DEV = ("127.0.0.1", 40000), ("127.0.0.1", 5000)
PTZ = b"#TPUG2wPTZ006A"
GAC = b"#tpGUCrGACFF36ED5A0048E3"


def test_in_order_out_of_order_and_retransmitted_segments():
    s = TcpStream()
    assert s.add(99, TCP_SYN, b"") == []
    assert [d.data for d in s.add(100, 0, b"abc")] == [b"abc"]
    assert s.add(106, 0, b"ghi") == []  # waits for 103..105
    assert [d.data for d in s.add(100, 0, b"abcd")] == [b"d"]  # overlap: only the new byte
    assert [d.data for d in s.add(103, 0, b"def")] == [b"ef", b"ghi"]
    assert s.add(100, 0, b"abcdefghi") == []  # pure retransmission


def test_sequence_numbers_wrap():
    s = TcpStream()
    s.add(0xFFFFFFFE, TCP_SYN, b"")
    assert [d.data for d in s.add(0xFFFFFFFF, 0, b"ab")] == [b"ab"]
    assert [d.data for d in s.add(1, 0, b"cd")] == [b"cd"]


def test_a_hole_is_skipped_and_reported_when_too_much_waits():
    s = TcpStream(max_pending=8)
    s.add(0, 0, b"a")
    assert s.add(10, 0, b"12345") == []
    got = s.add(15, 0, b"6789")  # 9 bytes wait > 8: skip the 9-byte hole
    assert [(d.data, d.gap) for d in got] == [(b"12345", 9), (b"6789", 0)]
    s2 = TcpStream()
    s2.add(0, 0, b"a")
    s2.add(5, 0, b"xyz")
    assert [(d.data, d.gap) for d in s2.finish()] == [(b"xyz", 4)]


class _CountingAhead:
    """Counts the sequence-number comparisons a TcpStream makes (the work it does)."""

    def __init__(self) -> None:
        self.calls = 0
        self.real = tcpstream._ahead

    def __call__(self, a: int, b: int) -> int:
        self.calls += 1
        return self.real(a, b)


@pytest.mark.parametrize("order", ["reversed", "holes"])
def test_reassembly_work_grows_linearly_with_waiting_segments(monkeypatch, order):
    """3,000 one-byte segments in reverse order (or each after a hole) cost ~9 million comparisons
    before (every waiting segment compared again per delivered one: 32,000 took 90 s, a 256 KiB
    backlog of them hours); now one per segment."""
    counter = _CountingAhead()
    monkeypatch.setattr(tcpstream, "_ahead", counter)
    n = 3000
    s = TcpStream()
    s.add(0, TCP_SYN, b"")
    if order == "reversed":
        for i in range(n, 0, -1):
            assert s.add(1 + i, 0, bytes([65 + i % 26])) == []
        got = s.add(1, 0, b"@")
        assert b"".join(d.data for d in got) == b"@" + bytes(65 + i % 26 for i in range(1, n + 1))
        assert [d.gap for d in got] == [0] * (n + 1)
    else:
        for i in range(n):
            assert s.add(2 + 2 * i, 0, b"x") == []
        got = s.finish()
        assert [(d.data, d.gap) for d in got] == [(b"x", 1)] * n
    assert counter.calls <= 4 * n
    assert s.finish() == []


def test_a_new_syn_restarts_the_stream_where_it_says():
    s = TcpStream()
    s.add(99, TCP_SYN, b"")
    assert [d.data for d in s.add(100, 0, b"ab")] == [b"ab"]
    s.add(5000, TCP_SYN, b"")  # the port pair reused by a new connection
    assert [d.data for d in s.add(5001, 0, b"cd")] == [b"cd"]
    assert s.next_seq == 5003


def test_the_end_of_a_one_sided_conversation_names_both_endpoints(tmp_path):
    """An incomplete frame left at the end of a TCP stream whose peer never sent: the record was
    addressed from the sender to itself."""
    path = tmp_path / "half.pcap"
    with PcapWriter(path) as w:
        w.write(1.0, build_packet("tcp", HOST, DEV, PTZ + PTZ[:6], seq=1000, flags=TCP_PSH | TCP_ACK))
    got = [x for x in frames_in_capture(path) if isinstance(x, WireFrame)]
    assert [(type(x.item).__name__, x.src, x.dst) for x in got] == [("Frame", HOST, DEV), ("Diagnostic", HOST, DEV)]


def _frames(path) -> list[Frame | Diagnostic]:
    return [x.item for x in frames_in_capture(path) if isinstance(x, WireFrame)]


def test_frames_split_at_every_byte_over_tcp(tmp_path):
    stream = PTZ + b"\r\n" + GAC + PTZ
    for cut in range(1, len(stream)):
        path = tmp_path / f"cut{cut}.pcap"
        with CaptureWriter(path) as w:
            w.tcp(HOST, DEV, stream[:cut], ts=1.0)
            w.tcp(HOST, DEV, stream[cut:], ts=2.0)
        got = _frames(path)
        assert [f.ident for f in got if isinstance(f, Frame)] == ["PTZ", "GAC", "PTZ"], cut
        assert not [d for d in got if isinstance(d, Diagnostic)], cut


def test_reordered_and_duplicated_tcp_packets(tmp_path):
    stream = (PTZ + GAC) * 5
    rng = random.Random(3)
    pieces, at = [], 0
    while at < len(stream):
        n = rng.randrange(1, 20)
        pieces.append((1000 + at, stream[at : at + n]))
        at += n
    shuffled = pieces[:1] + rng.sample(pieces[1:], len(pieces) - 1) + rng.sample(pieces, 5)
    path = tmp_path / "shuffled.pcap"
    with PcapWriter(path) as w:
        w.write(0.5, build_packet("tcp", HOST, DEV, b"", seq=999, flags=TCP_SYN))
        for i, (seq, data) in enumerate(shuffled):
            w.write(1.0 + i, build_packet("tcp", HOST, DEV, data, seq=seq, flags=TCP_PSH | TCP_ACK))
    assert [f.ident for f in _frames(path) if isinstance(f, Frame)] == ["PTZ", "GAC"] * 5


def test_udp_datagram_with_several_frames_and_garbage(tmp_path):
    path = tmp_path / "udp.pcap"
    with CaptureWriter(path) as w:
        w.udp(HOST, DEV, PTZ + b"\r\nxx" + GAC + GAC[:-1] + b"0", ts=1.0)
    got = _frames(path)
    kinds = [f.ident if isinstance(f, Frame) else f.kind for f in got]
    assert kinds == ["PTZ", "garbage", "GAC", "bad_checksum"]


def test_conversations_by_port_heuristic_and_filter(tmp_path):
    path = tmp_path / "mixed.pcap"
    other, dns = ("127.0.0.1", 7777), ("127.0.0.1", 53)
    with CaptureWriter(path) as w:
        w.udp(HOST, DEV, b"hello", ts=1.0)  # documented port: TOP, even this garbage
        w.udp(HOST, other, PTZ, ts=2.0)  # undocumented port, but starts with a TOP header
        w.udp(HOST, other, b"later bytes", ts=3.0)  # ... so the conversation is TOP
        w.udp(HOST, dns, b"\x12\x34 a DNS query", ts=4.0)  # never TOP: passed over silently
        w.udp(("::1", 40001), ("::1", 6000), PTZ, ts=5.0)
    every = [x for x in frames_in_capture(path) if isinstance(x, WireFrame)]
    assert [(x.number, x.dialect) for x in every] == [(1, "skydroid"), (2, None), (3, None), (5, None)]
    only = [x.number for x in frames_in_capture(path, ports=[7777]) if isinstance(x, WireFrame)]
    assert only == [2, 3]
    forced = [x.number for x in frames_in_capture(path, ports=[53]) if isinstance(x, WireFrame)]
    assert forced == [4]  # a filter makes the conversation TOP whatever it holds
    v6 = [x.src for x in frames_in_capture(path, addresses=["0:0::1"]) if isinstance(x, WireFrame)]
    assert v6 == [("::1", 40001)]


def test_lost_tcp_segment_is_noted_and_parsing_goes_on(tmp_path):
    path = tmp_path / "lost.pcap"
    with PcapWriter(path) as w:
        w.write(1.0, build_packet("tcp", HOST, DEV, b"", seq=0, flags=TCP_SYN))
        w.write(2.0, build_packet("tcp", HOST, DEV, PTZ + GAC[:5], seq=1))
        # GAC[5:15] never captured
        w.write(3.0, build_packet("tcp", HOST, DEV, GAC[15:] + PTZ, seq=1 + len(PTZ) + 15))
    got = list(frames_in_capture(path))
    notes = [x for x in got if isinstance(x, PacketNote)]
    assert len(notes) == 1 and "10 bytes missing" in notes[0].detail
    frames = [x.item.ident for x in got if isinstance(x, WireFrame) and isinstance(x.item, Frame)]
    assert frames == ["PTZ", "PTZ"]


@pytest.mark.parametrize("v6", [False, True])
def test_capture_writer_tcp_handshake_and_close(tmp_path, v6):
    a, b = (("::1", 40000), ("::1", 5000)) if v6 else (HOST, DEV)
    path = tmp_path / "hs.pcap"
    with CaptureWriter(path) as w:
        w.tcp(b, a, GAC, ts=1.0, client=a)  # the device speaks first; the host opened
        w.tcp(a, b, PTZ, ts=2.0)
    got = [x for x in frames_in_capture(path) if isinstance(x, WireFrame)]
    assert [(x.src, x.item.ident) for x in got] == [(b, "GAC"), (a, "PTZ")]  # type: ignore[union-attr]
