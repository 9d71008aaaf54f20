"""The dissector on the wire: several frames per datagram, line ends and garbage between frames,
frames split across TCP segments, expert infos, the Info column, filters and the dialect choice.
Frame boundaries are compared with topgimbal's own FrameParser on random streams."""

from __future__ import annotations

import random
from typing import Any

import pytest

from topgimbal import encode
from topgimbal.protocol import Diagnostic, Frame, FrameParser, get_dialect, make_frame
from topgimbal.wire import CaptureWriter

from .tshark import experts, run_tshark, top_layers, values

pytestmark = pytest.mark.external

HOST, SKYDROID, TOPOTEK, OTHER = ("127.0.0.1", 40000), ("127.0.0.1", 5000), ("127.0.0.1", 9003), ("127.0.0.1", 7777)
GAC = get_dialect("skydroid").response(
    encode("skydroid", "GAC", read=True), yaw_deg=-2.02, pitch_deg=-47.74, roll_deg=0.72
)
PTZ = b"#TPUG2wPTZ006A"


def _capture(tmp_path, name: str, packets: list[tuple[Any, Any, bytes]], transport: str = "udp"):
    path = tmp_path / name
    with CaptureWriter(path) as w:
        for i, (src, dst, payload) in enumerate(packets):
            if transport == "udp":
                w.udp(src, dst, payload, ts=1_700_000_000 + i * 0.01)
            else:
                w.tcp(src, dst, payload, ts=1_700_000_000 + i * 0.01, client=HOST)
    return path


def _info(dissector, capture) -> list[str]:
    out = run_tshark(dissector, capture, "-T", "fields", "-e", "_ws.col.Info")
    return out.splitlines()


def test_info_column_reads_like_the_issue_says(dissector, tmp_path):
    capture = _capture(tmp_path, "gac.pcap", [(SKYDROID, HOST, GAC.to_bytes())])
    assert _info(dissector, capture) == ["GAC attitude yaw=-2.02 pitch=-47.74 roll=0.72"]


def test_several_frames_line_ends_and_garbage_in_one_datagram(dissector, tmp_path):
    payload = PTZ + b"\r\n" + b"junk" + GAC.to_bytes() + b"\r\n"
    capture = _capture(tmp_path, "multi.pcap", [(HOST, SKYDROID, payload)])
    [frames] = top_layers(dissector, capture)
    assert [values(f, "top.id") for f in frames] == [["PTZ"], [], ["GAC"]]
    assert values(frames[1], "top.garbage")[0].replace(":", "") == b"\r\njunk".hex()  # as FrameParser reports it
    assert experts(frames[1]) == ["top.expert.garbage"]
    assert experts(frames[0]) == [] and experts(frames[2]) == []
    assert _info(dissector, capture) == [
        "PTZ gimbal_control action=stop | GAC attitude yaw=-2.02 pitch=-47.74 roll=0.72"
    ]


def test_expert_infos(dissector, tmp_path):
    bad_crc = PTZ[:-1] + b"B"
    unknown = make_frame("XYZ", "00", rw="w").to_bytes()
    c12_version = b"#tpDU3rVER0105025A"  # a real C12: length 3, six data characters
    truncated = GAC.to_bytes()[:-4]
    no_form = make_frame("GAC", "12345", src="G", dst="U", rw="r").to_bytes()
    oversize = b"#TpUG\x08\x00GAC" + b"0" * 10
    capture = _capture(
        tmp_path,
        "experts.pcap",
        [(HOST, SKYDROID, p) for p in (bad_crc, unknown, c12_version, truncated, no_form, oversize)],
    )
    packets = top_layers(dissector, capture)
    raised = [sorted({e for f in frames for e in experts(f)}) for frames in packets]
    assert raised == [
        ["top.expert.bad_checksum"],
        ["top.expert.unknown_id"],
        ["top.expert.bad_length"],
        ["top.expert.bad_length"],
        ["top.expert.bad_fields"],
        ["top.expert.bad_length", "top.expert.garbage"],
    ]
    assert values(packets[0][0], "top.checksum.status") == ["0"]
    assert values(packets[0][0], "top.checksum.expected") == ["6A"]
    assert values(packets[2][0], "top.field.version") and values(packets[2][0], "top.checksum.status") == ["1"]


def test_display_filters_under_one_prefix(dissector, tmp_path):
    packets = [(HOST, SKYDROID, PTZ), (SKYDROID, HOST, GAC.to_bytes()), (HOST, SKYDROID, PTZ[:-1] + b"0")]
    capture = _capture(tmp_path, "filters.pcap", packets)
    frames = run_tshark(
        dissector, capture, "-Y", 'top.id == "GAC" && top.field.yaw_deg < 0', "-T", "fields", "-e", "frame.number"
    )
    assert frames.split() == ["2"]
    bad = run_tshark(dissector, capture, "-Y", 'top.checksum.status == "Bad"', "-T", "fields", "-e", "frame.number")
    assert bad.split() == ["3"]
    enum = run_tshark(dissector, capture, "-Y", 'top.field.action == "stop"', "-T", "fields", "-e", "top.name")
    assert enum.split() == ["gimbal_control", "gimbal_control"]


def test_dialect_by_port_then_by_frame(dissector, tmp_path):
    # GAC means the same in both dialects, so the port decides; on another port SkyDroid is
    # tried first, unless the frame carries TOPOTEK's network host address P.
    topotek_gac = make_frame("GAC", GAC.data, src="G", dst="P", rw="r").to_bytes()
    packets = [
        (SKYDROID, HOST, GAC.to_bytes()),
        (TOPOTEK, HOST, GAC.to_bytes()),
        (OTHER, HOST, GAC.to_bytes()),
        (OTHER, HOST, topotek_gac),
    ]
    capture = _capture(tmp_path, "dialects.pcap", packets)
    got = [values(frames[0], "top.dialect")[0] for frames in top_layers(dissector, capture)]
    assert got == ["skydroid", "topotek", "skydroid", "topotek"]
    forced = run_tshark(dissector, capture, "-o", "top.dialect:topotek", "-T", "fields", "-e", "top.dialect")
    assert forced.split() == ["topotek"] * 4


def test_heuristic_takes_tcp_on_any_port_and_reassembles(dissector, tmp_path):
    stream = PTZ + GAC.to_bytes() + b"\r\n" + PTZ
    cuts = [3, 9, 10, 22, 31, len(stream)]  # splits inside header, data and checksum
    pieces, at = [], 0
    for c in cuts:
        pieces.append((HOST, OTHER, stream[at:c]))
        at = c
    capture = _capture(tmp_path, "tcp.pcap", pieces, transport="tcp")
    ids = [values(f, "top.id")[0] for frames in top_layers(dissector, capture) for f in frames if values(f, "top.id")]
    assert ids == ["PTZ", "GAC", "PTZ"]


# -- frame boundaries: the dissector's scanner against FrameParser --------------------------------


def _pool() -> list[bytes]:
    sky, topo = get_dialect("skydroid"), get_dialect("topotek")
    frames = [
        PTZ,
        GAC.to_bytes(),
        b"#tpDU3rVER0105025A",
        sky.encode("GAY", yaw_deg=-50.0, speed_deg_s=5).to_bytes(),
        topo.encode("GIP", pitch_deg=12.5, speed_deg_s=3).to_bytes(),
        b"#tpGPCrGACFF36ED5A0048DE",
        b"#tpgpcrgacff36ed5a0048de"[:0] + b"#tpGPCrGACff36ed5a0048de"[:-2] + b"de",
    ]
    return frames


def _mutate(rng: random.Random, frame: bytes) -> bytes:
    kind = rng.choice(["ok", "ok", "ok", "crc", "trunc", "len", "garbage", "crlf", "hash"])
    if kind == "crc":
        return frame[:-1] + (b"0" if frame[-1:] != b"0" else b"1")
    if kind == "trunc":
        return frame[: rng.randrange(1, len(frame))]
    if kind == "len" and frame[1:3] in (b"TP", b"tp"):
        return frame[:5] + rng.choice(b"0123456789ABCDEF").to_bytes(1, "big") + frame[6:]
    if kind == "garbage":
        return bytes(rng.choice(b"xyz 0#TPUG\r\n") for _ in range(rng.randrange(1, 6))) + frame
    if kind == "crlf":
        return frame + b"\r\n"
    if kind == "hash":
        return b"#" + frame
    return frame


def _shown(data: bytes) -> str:
    """Data as the dissector shows it: printable ASCII, anything else as a \\xNN escape."""
    return "".join(chr(b) if 0x20 <= b < 0x7F else f"\\x{b:02x}" for b in data)


def _python_items(items: list[Frame | Diagnostic]) -> list[tuple[Any, ...]]:
    out: list[tuple[Any, ...]] = []
    for it in items:
        if isinstance(it, Frame):
            out.append(("frame", it.ident, _shown(it.data), "1"))
        elif it.kind == "bad_checksum":  # the frame at its declared length
            out.append(("frame", it.raw[7:10].decode("latin-1"), _shown(it.raw[10:-2]), "0"))
        elif it.kind != "length_mismatch":
            out.append(("skip", it.raw.hex()))
    return out


def _lua_items(frames: list[dict[str, Any]]) -> list[tuple[Any, ...]]:
    out: list[tuple[Any, ...]] = []
    for f in frames:
        garbage = values(f, "top.garbage")
        if garbage:
            out.append(("skip", garbage[0].replace(":", "")))
        else:
            data = values(f, "top.data")
            out.append(("frame", values(f, "top.id")[0], data[0] if data else "", values(f, "top.checksum.status")[0]))
    return out


@pytest.mark.parametrize("seed", [1, 2])
def test_datagram_boundaries_match_the_frame_parser(dissector, tmp_path, seed):
    rng = random.Random(seed)
    pool = _pool()
    datagrams = [b"".join(_mutate(rng, rng.choice(pool)) for _ in range(rng.randrange(1, 5))) for _ in range(150)]
    capture = _capture(tmp_path, "fuzz.pcap", [(HOST, SKYDROID, d) for d in datagrams])
    packets = top_layers(dissector, capture)
    lua = [_lua_items(frames) for frames in packets]
    expected = [_python_items(FrameParser().feed_datagram(d)) for d in datagrams]
    # tshark lists packets in which the dissector added something; pure CR LF adds nothing
    expected_nonempty = [e for e in expected if e]
    lua_nonempty = [x for x in lua if x]
    assert lua_nonempty == expected_nonempty


@pytest.mark.parametrize("seed", [3, 4])
def test_stream_boundaries_match_the_frame_parser(dissector, tmp_path, seed):
    rng = random.Random(seed)
    pool = _pool()
    stream = b"".join(_mutate(rng, rng.choice(pool)) for _ in range(60)) + PTZ
    pieces, at = [], 0
    while at < len(stream):
        n = rng.randrange(1, 40)
        pieces.append(stream[at : at + n])
        at += n
    capture = _capture(tmp_path, "stream.pcap", [(HOST, SKYDROID, p) for p in pieces], transport="tcp")
    lua = [item for frames in top_layers(dissector, capture) for item in _lua_items(frames)]
    parser = FrameParser()
    expected = [item for p in pieces for item in _python_items(parser.feed(p))]
    assert lua == expected
    assert sum(1 for x in expected if x[0] == "frame") > 30
