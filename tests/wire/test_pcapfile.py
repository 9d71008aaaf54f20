"""Capture files: our writer and reader round-trip, the reader reads what Wireshark's own tools
write (editcap, text2pcap, tshark) and every link type a loopback or LAN capture has, and a damaged
file is reported, never raised past a clear error."""

from __future__ import annotations

import shutil
import struct
import subprocess
import sys
from pathlib import Path

import pytest

from topgimbal.wire import (
    CaptureError,
    CaptureProblem,
    CaptureRecord,
    CaptureWriter,
    PcapngWriter,
    PcapWriter,
    read_capture,
)
from topgimbal.wire.capture import PacketNote, WireFrame, frames_in_capture
from topgimbal.wire.packets import TCP_ACK, TCP_PSH, Segment, build_packet, parse_packet
from topgimbal.wire.pcapfile import (
    LINKTYPE_ETHERNET,
    LINKTYPE_IPV4,
    LINKTYPE_LINUX_SLL,
    LINKTYPE_LINUX_SLL2,
    LINKTYPE_LOOP,
    LINKTYPE_NULL,
    LINKTYPE_RAW,
)

from .tshark import run_tshark, top_layers, values

pytestmark = pytest.mark.external

PTZ = b"#TPUG2wPTZ006A"
GAC = b"#tpGUCrGACFF36ED5A0048E3"


def _records(path: Path) -> list[CaptureRecord]:
    got = list(read_capture(path))
    assert all(isinstance(r, CaptureRecord) for r in got), got
    return got  # type: ignore[return-value]


@pytest.mark.parametrize("cls", [PcapWriter, PcapngWriter])
def test_writer_reader_round_trip(tmp_path, cls):
    path = tmp_path / ("x.pcapng" if cls is PcapngWriter else "x.pcap")
    packets = [build_packet("udp", ("127.0.0.1", 40000), ("127.0.0.1", 5000), PTZ), b"\x00" * 60]
    with cls(path) as w:
        w.write(1_700_000_000.25, packets[0])
        w.write(1_700_000_001.000001, packets[1])
    recs = _records(path)
    assert [r.data for r in recs] == packets
    assert [r.number for r in recs] == [1, 2]
    assert recs[0].ts == pytest.approx(1_700_000_000.25, abs=1e-6)
    assert recs[1].ts == pytest.approx(1_700_000_001.000001, abs=1e-6)
    assert {r.linktype for r in recs} == {LINKTYPE_ETHERNET}


@pytest.mark.parametrize("name", ["b.pcap", "b.pcapng"])
def test_buffered_writer_holds_packets_until_flush(tmp_path, name):
    """flush_each=False (the proxy's pcap): packets wait for flush(); the file is a valid, empty
    capture meanwhile, and close() writes what waits."""
    path = tmp_path / name
    w = CaptureWriter(path, flush_each=False)
    assert _records(path) == []  # the file header was written at once
    for i in range(3):
        w.udp(("127.0.0.1", 40000), ("127.0.0.1", 5000), PTZ, ts=100.0 + i)
    assert _records(path) == []
    w.flush()
    assert len(_records(path)) == 3
    w.udp(("127.0.0.1", 5000), ("127.0.0.1", 40000), GAC, ts=104.0)
    w.close()
    assert [r.number for r in _records(path)] == [1, 2, 3, 4]


def _editcap(src: Path, dst: Path, fmt: str) -> None:
    editcap = shutil.which("editcap")
    assert editcap, "editcap comes with tshark: run `make tshark-deps`"
    subprocess.run([editcap, "-F", fmt, str(src), str(dst)], check=True, capture_output=True)


@pytest.mark.parametrize("fmt", ["pcapng", "nsecpcap", "pcap"])
def test_reader_reads_files_written_by_editcap(tmp_path, fmt):
    ours = tmp_path / "ours.pcap"
    with CaptureWriter(ours) as w:
        w.udp(("127.0.0.1", 40000), ("127.0.0.1", 5000), PTZ, ts=1_700_000_000.5)
        w.udp(("127.0.0.1", 5000), ("127.0.0.1", 40000), GAC, ts=1_700_000_000.75)
    theirs = tmp_path / f"theirs.{fmt}"
    _editcap(ours, theirs, fmt)
    assert theirs.read_bytes() != ours.read_bytes() or fmt == "pcap"
    mine, converted = _records(ours), _records(theirs)
    assert [r.data for r in converted] == [r.data for r in mine]
    assert [round(r.ts, 6) for r in converted] == [round(r.ts, 6) for r in mine]


def _text2pcap(tmp_path: Path, payload: bytes, *args: str) -> Path:
    text2pcap = shutil.which("text2pcap")
    assert text2pcap, "text2pcap comes with tshark's package (wireshark-common): run `make tshark-deps`"
    dump = tmp_path / "dump.txt"
    lines = []
    for at in range(0, len(payload), 16):
        chunk = payload[at : at + 16]
        lines.append(f"{at:06x} " + " ".join(f"{b:02x}" for b in chunk))
    dump.write_text("\n".join(lines) + "\n")
    out = tmp_path / ("t2p.pcapng" if "-n" in args else "t2p.pcap")
    subprocess.run([text2pcap, *args, str(dump), str(out)], check=True, capture_output=True)
    return out


@pytest.mark.parametrize(
    ("args", "transport", "family"),
    [
        (("-4", "127.0.0.1,127.0.0.1", "-u", "40000,5000"), "udp", "127.0.0.1"),
        (("-n", "-4", "127.0.0.1,127.0.0.1", "-u", "40000,5000"), "udp", "127.0.0.1"),
        (("-4", "127.0.0.1,127.0.0.1", "-T", "40000,5000"), "tcp", "127.0.0.1"),
        (("-6", "::1,::1", "-u", "40000,5000"), "udp", "::1"),
        (("-4", "10.1.2.3,10.1.2.4", "-T", "40000,5000"), "tcp", "10.1.2.3"),
    ],
)
def test_frames_from_text2pcap_files(tmp_path, args, transport, family):
    """text2pcap (Wireshark's own tool) builds the Ethernet/IP/UDP-or-TCP headers here."""
    capture = _text2pcap(tmp_path, PTZ + b"\r\n" + GAC, *args)
    got = [x for x in frames_in_capture(capture) if isinstance(x, WireFrame)]
    assert [g.item.ident for g in got] == ["PTZ", "GAC"]  # type: ignore[union-attr]
    assert {g.transport for g in got} == {transport}
    assert got[0].src == (family, 40000) and got[0].dst[1] == 5000
    assert got[0].dialect == "skydroid"  # port 5000 is documented for SkyDroid


# -- link types -------------------------------------------------------------------------------------


def _ip_packet(payload: bytes, v6: bool = False) -> bytes:
    a = ("::1", 40000) if v6 else ("127.0.0.1", 40000)
    b = ("::1", 9003) if v6 else ("127.0.0.1", 9003)
    return build_packet("udp", a, b, payload)[14:]  # without the Ethernet header


LINK_HEADERS = {
    LINKTYPE_NULL: lambda v6: struct.pack("<I", 30 if v6 else 2),  # macOS: AF_INET6 = 30
    LINKTYPE_LOOP: lambda v6: struct.pack(">I", 24 if v6 else 2),  # OpenBSD
    LINKTYPE_RAW: lambda v6: b"",
    LINKTYPE_LINUX_SLL: lambda v6: struct.pack("!HHH8sH", 0, 772, 6, b"\0" * 8, 0x86DD if v6 else 0x0800),
    LINKTYPE_LINUX_SLL2: lambda v6: struct.pack("!HHIHBB8s", 0x86DD if v6 else 0x0800, 0, 1, 772, 0, 6, b"\0" * 8),
    LINKTYPE_ETHERNET: lambda v6: b"\0" * 12 + struct.pack("!HHH", 0x8100, 5, 0x86DD if v6 else 0x0800),  # VLAN 5
    LINKTYPE_IPV4: lambda v6: b"",
}


@pytest.mark.parametrize("linktype", sorted(LINK_HEADERS))
@pytest.mark.parametrize("v6", [False, True])
def test_link_types(tmp_path, dissector, linktype, v6):
    if linktype == LINKTYPE_IPV4 and v6:
        linktype = 229  # LINKTYPE_IPV6
    header = LINK_HEADERS.get(linktype, lambda v6: b"")(v6)
    path = tmp_path / "link.pcap"
    with PcapWriter(path, linktype) as w:
        w.write(1.0, header + _ip_packet(GAC.replace(b"GU", b"GP")[:-2] + b"DE", v6))
    got = [x for x in frames_in_capture(path) if isinstance(x, WireFrame)]
    assert [g.item.ident for g in got] == ["GAC"]  # type: ignore[union-attr]
    assert got[0].dialect == "topotek"  # port 9003
    # and Wireshark agrees on the link layer: it finds the same frame in the same file
    [frames] = top_layers(dissector, path)
    assert values(frames[0], "top.id") == ["GAC"] and values(frames[0], "top.dialect") == ["topotek"]


# -- damaged files -----------------------------------------------------------------------------------


def test_not_a_capture_is_a_clear_error(tmp_path):
    path = tmp_path / "x.pcap"
    path.write_bytes(b"#TPUG2wPTZ006A\n")
    with pytest.raises(CaptureError, match="not a pcap or pcapng file"):
        list(read_capture(path))
    with pytest.raises(CaptureError, match="No such file"):
        list(read_capture(tmp_path / "missing.pcap"))


@pytest.mark.parametrize("suffix", ["pcap", "pcapng"])
def test_truncated_capture_keeps_what_was_read(tmp_path, suffix):
    path = tmp_path / f"cut.{suffix}"
    with CaptureWriter(path) as w:
        for i in range(5):
            w.udp(("127.0.0.1", 40000), ("127.0.0.1", 5000), PTZ, ts=10.0 + i)
    data = path.read_bytes()
    path.write_bytes(data[:-7])  # the last record loses its end
    got = list(read_capture(path))
    assert [type(x).__name__ for x in got] == ["CaptureRecord"] * 4 + ["CaptureProblem"]
    assert "truncated" in str(got[-1])
    frames = [x for x in frames_in_capture(path) if isinstance(x, WireFrame)]
    assert len(frames) == 4


def test_corrupt_record_length(tmp_path):
    path = tmp_path / "bad.pcap"
    with PcapWriter(path) as w:
        w.write(1.0, b"\0" * 40)
    data = bytearray(path.read_bytes())
    data[24 + 8 : 24 + 12] = struct.pack("<I", 1 << 30)  # incl_len of the first record
    path.write_bytes(bytes(data))
    [problem] = list(read_capture(path))
    assert isinstance(problem, CaptureProblem) and "corrupt" in problem.detail


def test_empty_records_and_bad_udp_lengths_are_noted(tmp_path):
    """Records of 0 bytes, a UDP length below its header or beyond the packet: each noted with
    what is wrong (tshark flags them too), the good packet after them decoded."""
    good = build_packet("udp", ("127.0.0.1", 40000), ("127.0.0.1", 5000), PTZ)
    at = 14 + 20 + 4  # the UDP length field
    short, long = bytearray(good), bytearray(good)
    short[at : at + 2] = struct.pack("!H", 3)
    long[at : at + 2] = struct.pack("!H", 60000)
    path = tmp_path / "odd.pcap"
    with PcapWriter(path) as w:
        for i, packet in enumerate((b"", bytes(short), bytes(long), good)):
            w.write(1.0 + i, packet)
    got = list(frames_in_capture(path))
    notes = [(x.number, x.detail) for x in got if isinstance(x, PacketNote)]
    assert notes == [
        (1, "malformed packet: its 0 bytes end inside a header (unpack requires a buffer of 2 bytes)"),
        (2, f"UDP length 3 does not fit the {8 + len(PTZ)}-byte payload"),
        (3, f"UDP length 60000 does not fit the {8 + len(PTZ)}-byte payload"),
    ]
    assert [x.number for x in got if isinstance(x, WireFrame)] == [4]


def test_unparseable_packets_are_noted_not_raised(tmp_path):
    path = tmp_path / "odd.pcap"
    good = build_packet("udp", ("127.0.0.1", 40000), ("127.0.0.1", 5000), PTZ)
    fragment = bytearray(good)
    fragment[14 + 6 : 14 + 8] = struct.pack("!H", 0x2000)  # more fragments
    with PcapWriter(path) as w:
        w.write(1.0, good[:20])  # cut inside the IP header
        w.write(2.0, bytes(fragment))
        w.write(3.0, b"\xff" * 12 + b"\x08\x06" + b"\0" * 28)  # ARP: not ours, silently skipped
        w.write(4.0, good)
    got = list(frames_in_capture(path))
    notes = [x for x in got if not isinstance(x, WireFrame)]
    assert [n.number for n in notes] == [1, 2]  # type: ignore[union-attr]
    assert "fragment" in notes[1].detail  # type: ignore[union-attr]
    assert [x.number for x in got if isinstance(x, WireFrame)] == [4]


# -- packets --------------------------------------------------------------------------------------


@pytest.mark.parametrize("host", ["127.0.0.1", "::1"])
@pytest.mark.parametrize("transport", ["udp", "tcp"])
def test_build_and_parse_packets(host, transport):
    pkt = build_packet(transport, (host, 40000), (host, 5000), PTZ, seq=77, flags=TCP_PSH | TCP_ACK)
    seg = parse_packet(LINKTYPE_ETHERNET, pkt)
    assert isinstance(seg, Segment)
    assert (seg.transport, seg.src, seg.dst, seg.payload) == (transport, (host, 40000), (host, 5000), PTZ)
    if transport == "tcp":
        assert seg.seq == 77 and seg.flags == TCP_PSH | TCP_ACK


def test_tshark_finds_our_checksums_right(tmp_path):
    path = tmp_path / "sums.pcap"
    with CaptureWriter(path) as w:
        w.udp(("127.0.0.1", 40000), ("127.0.0.1", 5000), PTZ)
        w.tcp(("::1", 40000), ("::1", 5000), GAC)
    out = run_tshark(
        None,
        path,
        "-o", "ip.check_checksum:TRUE", "-o", "udp.check_checksum:TRUE", "-o", "tcp.check_checksum:TRUE",
        "-T", "fields", "-e", "ip.checksum.status", "-e", "udp.checksum.status", "-e", "tcp.checksum.status",
    )  # fmt: skip
    statuses = {s for line in out.splitlines() for s in line.split("\t") if s}
    assert statuses == {"1"}  # Wireshark's checksum status: 0 bad, 1 good, 2 unverified


def test_big_endian_pcap(tmp_path):
    """A pcap written on a big-endian machine (SPARC, PowerPC): every header field swapped."""
    packet = build_packet("udp", ("127.0.0.1", 40000), ("127.0.0.1", 5000), PTZ)
    path = tmp_path / "be.pcap"
    path.write_bytes(
        struct.pack(">IHHiIII", 0xA1B2C3D4, 2, 4, 0, 0, 65535, LINKTYPE_ETHERNET)
        + struct.pack(">IIII", 1_700_000_000, 250_000, len(packet), len(packet))
        + packet
    )
    [rec] = _records(path)
    assert rec.data == packet and rec.ts == pytest.approx(1_700_000_000.25)
    assert [x.item.ident for x in frames_in_capture(path) if isinstance(x, WireFrame)] == ["PTZ"]  # type: ignore[union-attr]


def _block(btype: int, body: bytes, length: int | None = None) -> bytes:
    body += b"\0" * (-len(body) % 4)
    n = len(body) + 12 if length is None else length
    return struct.pack("<II", btype, n) + body + struct.pack("<I", n)


@pytest.mark.parametrize("length", [0xFFFFFFF0, 8, 30])
def test_a_section_header_with_a_corrupt_length_is_reported_before_it_is_read(tmp_path, length):
    """The section header's length was used to size a read unchecked: a claimed 4 GiB allocated
    4 GiB (MemoryError under a memory limit), a short one was 'block truncated'."""
    path = tmp_path / "shb.pcapng"
    path.write_bytes(struct.pack("<III", 0x0A0D0D0A, length, 0x1A2B3C4D) + b"\0" * 40)
    [problem] = list(read_capture(path))
    assert isinstance(problem, CaptureProblem) and problem.offset == 0
    assert f"section header: block length {length}: must be a multiple of 4 in 28.." in problem.detail


def test_a_huge_section_header_length_allocates_nothing(tmp_path):
    """Under a 1 GiB address-space limit, reading a file whose section header claims 4 GiB ends
    with the CaptureProblem, not a MemoryError."""
    path = tmp_path / "shb.pcapng"
    path.write_bytes(struct.pack("<III", 0x0A0D0D0A, 0xFFFFFFF0, 0x1A2B3C4D) + b"\0" * 40)
    code = (
        "import resource, sys; from topgimbal.wire import read_capture; "
        "resource.setrlimit(resource.RLIMIT_AS, (1 << 30, 1 << 30)); "
        "print([str(x) for x in read_capture(sys.argv[1])])"
    )
    proc = subprocess.run([sys.executable, "-c", code, str(path)], capture_output=True, text=True, timeout=60)
    assert proc.returncode == 0, proc.stderr
    assert "block length 4294967280" in proc.stdout


def test_pcapng_with_unknown_blocks_and_interfaces_of_other_link_types(tmp_path):
    """A second interface of a link type we do not decode: its packets are noted, the others
    decoded, an unknown block skipped; numbers stay Wireshark's."""
    packet = build_packet("udp", ("127.0.0.1", 40000), ("127.0.0.1", 5000), PTZ)
    shb = _block(0x0A0D0D0A, struct.pack("<IHHq", 0x1A2B3C4D, 1, 0, -1))
    idbs = _block(1, struct.pack("<HHI", LINKTYPE_ETHERNET, 0, 0xFFFFFFFF)) + _block(1, struct.pack("<HHI", 147, 0, 0))

    def epb(iface: int) -> bytes:
        return _block(6, struct.pack("<IIIII", iface, 0, 1_000_000, len(packet), len(packet)) + packet)

    path = tmp_path / "multi.pcapng"
    path.write_bytes(shb + idbs + _block(0x0BAD, b"vendor") + epb(0) + epb(1) + epb(0))
    got = list(frames_in_capture(path))
    notes = [x for x in got if isinstance(x, PacketNote)]
    assert [(n.number, "link type 147 is not supported" in n.detail) for n in notes] == [(2, True)]
    assert [x.number for x in got if isinstance(x, WireFrame)] == [1, 3]
