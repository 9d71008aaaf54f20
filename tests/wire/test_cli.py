"""The command line: `decode --pcap`, `dissector`, `pcap from-log`; and the committed dissector
is what the catalog generates now."""

from __future__ import annotations

import json
import re
import signal
import socket
import subprocess
import sys
from pathlib import Path

import pytest

from topgimbal.cli.main import main
from topgimbal.cli.protocol_cmds import RECORD_KEYS
from topgimbal.wire import CaptureRecord, CaptureWriter, generate_dissector, read_capture

from .tshark import top_layers, values

pytestmark = pytest.mark.external

HOST, SKY, SIP = ("127.0.0.1", 40000), ("127.0.0.1", 5000), ("127.0.0.1", 9003)
PTZ = b"#TPUG2wPTZ006A"
GAC = b"#tpGUCrGACFF36ED5A0048E3"
CONTRIB = Path(__file__).resolve().parents[2] / "contrib" / "wireshark" / "topgimbal.lua"


def test_committed_dissector_is_current():
    assert CONTRIB.read_text(encoding="utf-8") == generate_dissector(), (
        "contrib/wireshark/topgimbal.lua is stale: run `make docs` (topgimbal dissector -o ...)"
    )
    assert main(["dissector", "--check", str(CONTRIB)]) == 0


def test_dissector_command_writes_and_checks(tmp_path, capsys):
    out = tmp_path / "top.lua"
    assert main(["dissector", "-o", str(out)]) == 0
    assert out.read_text(encoding="utf-8") == generate_dissector()
    out.write_text(out.read_text(encoding="utf-8") + "-- edited\n", encoding="utf-8")
    assert main(["dissector", "--check", str(out)]) == 1
    assert "stale" in capsys.readouterr().err


def _session(path: Path) -> None:
    with CaptureWriter(path) as w:
        w.udp(HOST, SKY, PTZ, ts=100.0)
        w.udp(SKY, HOST, PTZ.replace(b"UG", b"GU")[:-2] + b"6A", ts=100.5)
        w.udp(SKY, HOST, GAC + b"\r\n" + GAC[:-1] + b"0", ts=101.0)  # one good, one bad checksum
        w.udp(("127.0.0.1", 9004), SIP, b"#TPPG2rGAC002D", ts=99.0)  # earlier in time
        w.tcp(HOST, ("127.0.0.1", 5000), PTZ[:6], ts=102.0)
        w.tcp(HOST, ("127.0.0.1", 5000), PTZ[6:], ts=102.1)


@pytest.mark.parametrize("name", ["s.pcap", "s.pcapng"])
def test_decode_pcap_json_in_time_order(tmp_path, capsys, name):
    path = tmp_path / name
    _session(path)
    rc = main(["decode", "--pcap", str(path), "--json"])
    lines = [json.loads(x) for x in capsys.readouterr().out.splitlines()]
    assert rc == 1  # one frame has a bad checksum
    assert all(set(RECORD_KEYS) <= set(r) for r in lines)
    assert [r["time"] for r in lines] == sorted(r["time"] for r in lines)
    assert [(r["id"], r["ok"], r["dir"], r["dialect"]) for r in lines] == [
        ("GAC", True, "out", "topotek"),  # port 9003 and 9004: TOPOTEK
        ("PTZ", True, "out", "skydroid"),
        ("PTZ", True, "in", "skydroid"),
        ("GAC", True, "in", "skydroid"),
        ("GAC", False, "in", "skydroid"),
        ("PTZ", True, "out", "skydroid"),
    ]
    assert lines[3]["fields"] == {"yaw_deg": -2.02, "pitch_deg": -47.74, "roll_deg": 0.72}
    assert lines[4]["error"].startswith("bad checksum")
    assert lines[5]["transport"] == "tcp" and lines[5]["packet"] == 9  # completed by the 2nd segment
    assert lines[1]["src_addr"] == "127.0.0.1:40000" and lines[1]["dst_addr"] == "127.0.0.1:5000"


def test_decode_pcap_human_and_filters(tmp_path, capsys):
    path = tmp_path / "s.pcap"
    _session(path)
    main(["decode", "--pcap", str(path), "--port", "9003"])
    out = capsys.readouterr().out
    assert out.count("ok") == 1 and "GAC attitude" in out and "decoded by the topotek dialect" in out
    assert "PTZ" not in out
    main(["decode", "--pcap", str(path), "--address", "127.0.0.2"])
    assert capsys.readouterr().out == ""
    main(["decode", "--pcap", str(path), "--dialect", "topotek", "--json", "--port", "5000"])
    assert {json.loads(x)["dialect"] for x in capsys.readouterr().out.splitlines()} == {"topotek"}


def test_decode_pcap_on_damaged_and_wrong_files(tmp_path, capsys):
    path = tmp_path / "cut.pcap"
    _session(path)
    path.write_bytes(path.read_bytes()[:-215])  # the FIN exchange (3 x 70 bytes) and into the last segment
    rc = main(["decode", "--pcap", str(path), "--json"])
    out, err = capsys.readouterr()
    assert rc == 1 and "truncated" in err
    got = [json.loads(x) for x in out.splitlines()]
    assert [r["id"] for r in got] == ["GAC", "PTZ", "PTZ", "GAC", "GAC", None]
    assert got[-1]["frame"] == "#TPUG2" and "incomplete frame at end of stream" in got[-1]["error"]
    text = tmp_path / "notes.txt"
    text.write_text("not a capture")
    assert main(["decode", "--pcap", str(text)]) == 1
    assert "not a pcap or pcapng file" in capsys.readouterr().err


def test_log_to_pcap(tmp_path, capsys, dissector):
    log = tmp_path / "session.jsonl"
    header = {"topgimbal_log": 1, "url": "udp://127.0.0.1:41234", "model": "SIP", "dialect": "topotek", "t": 1.0}
    out_frame = {"t": 10.0, "mono": 1.0, "dir": "out", "raw": "#TPPG2rGAC002D", "decoded": None}
    in_frame = {"t": 10.1, "mono": 1.1, "dir": "in", "raw": "#tpGPCrGACFF36ED5A0048DE", "decoded": None}
    lines = [json.dumps(x) for x in (header, out_frame, in_frame)] + ["{broken", json.dumps({"dir": "sideways"})]
    log.write_text("\n".join(lines) + "\n")
    pcap = tmp_path / "session.pcap"
    assert main(["pcap", "from-log", str(log), "-o", str(pcap)]) == 1  # two bad lines reported
    err = capsys.readouterr().err
    assert "line 4: not JSON" in err and "line 5" in err and "2 frames" in err
    packets = top_layers(dissector, pcap)
    assert [values(p[0], "top.id") for p in packets] == [["GAC"], ["GAC"]]
    # the client port 9004 tells Wireshark the dialect although the device port is not documented
    assert [values(p[0], "top.dialect") for p in packets] == [["topotek"], ["topotek"]]
    assert values(packets[1][0], "top.field.pitch_deg") == ["-47.74"]


def test_log_over_tcp_to_pcap(tmp_path, capsys):
    log = tmp_path / "tcp.jsonl"
    header = {"topgimbal_log": 1, "url": "tcp://[::1]:5000", "model": "C20", "dialect": "skydroid"}
    frames = [
        {"t": 5.0 + i, "dir": d, "raw": raw} for i, (d, raw) in enumerate([("out", PTZ.decode()), ("in", GAC.decode())])
    ]
    log.write_text("\n".join(json.dumps(x) for x in (header, *frames)) + "\n")
    pcap = tmp_path / "tcp.pcapng"
    assert main(["pcap", "from-log", str(log), "-o", str(pcap)]) == 0
    assert "TCP [::1]:40000 <-> [::1]:5000" in capsys.readouterr().err
    assert main(["decode", "--pcap", str(pcap), "--json"]) == 0
    got = [json.loads(x) for x in capsys.readouterr().out.splitlines()]
    assert [(r["id"], r["dir"], r["transport"]) for r in got] == [("PTZ", "out", "tcp"), ("GAC", "in", "tcp")]


@pytest.mark.parametrize("url", ["udp://127.0.0.1:5000", "tcp://127.0.0.1:5000"])
def test_log_lines_no_capture_can_hold_are_reported_and_skipped(tmp_path, capsys, url):
    """A time that is not finite, negative or past 2106, or a frame no datagram holds, stopped
    `pcap from-log` with a traceback (OverflowError, ValueError, struct.error) and left a capture
    cut short; now each is a reported line, and the rest of the log is written."""
    good = {"dir": "out", "raw": PTZ.decode()}
    bad = [{"t": t, **good} for t in ("NaN", "Infinity", -5, 1e12)]
    if url.startswith("udp"):  # over TCP it is split into segments (and garbage)
        bad.append({"t": 3.0, "dir": "in", "raw": "A" * 70_000})
    lines = [json.dumps({"topgimbal_log": 1, "url": url, "dialect": "skydroid"})]
    lines += [json.dumps(x).replace('"NaN"', "NaN").replace('"Infinity"', "Infinity") for x in bad]
    lines += [json.dumps({"t": 10.0 + i, **good}) for i in range(2)]
    log = tmp_path / "odd.jsonl"
    log.write_text("\n".join(lines) + "\n")
    pcap = tmp_path / "odd.pcap"
    assert main(["pcap", "from-log", str(log), "-o", str(pcap)]) == 1
    err = capsys.readouterr().err
    for n, t in ((2, "nan"), (3, "inf"), (4, "-5"), (5, "1000000000000.0")):
        assert f"line {n}: time {t}" in err and "a capture holds 0..4294967295 s" in err, err
    if url.startswith("udp"):
        assert "line 6: a 70000-byte datagram cannot be written: UDP holds at most 65507" in err
    assert "wrote" in err and "2 frames" in err
    assert main(["decode", "--pcap", str(pcap), "--json"]) == 0  # the handshake came before the data
    got = [json.loads(x) for x in capsys.readouterr().out.splitlines()]
    assert [r["time"] for r in got if r["id"] == "PTZ"] == [10.0, 11.0]


def test_a_log_header_with_a_broken_url_still_exports_the_frames(tmp_path, capsys):
    log = tmp_path / "hdr.jsonl"
    header = {"topgimbal_log": 1, "url": "udp://[::1:5000", "dialect": "skydroid"}
    log.write_text("\n".join(json.dumps(x) for x in (header, {"t": 1.0, "dir": "out", "raw": PTZ.decode()})))
    pcap = tmp_path / "hdr.pcap"
    assert main(["pcap", "from-log", str(log), "-o", str(pcap)]) == 1  # was: "error: Invalid IPv6 URL", nothing written
    err = capsys.readouterr().err
    assert "header: url 'udp://[::1:5000' is not a transport URL" in err and "1 frames" in err
    assert [type(x) for x in read_capture(pcap)] == [CaptureRecord]


@pytest.mark.integration
@pytest.mark.parametrize(("as_json", "stop"), [(True, signal.SIGTERM), (False, signal.SIGINT)])
def test_proxy_command_prints_each_frame(tmp_path, as_json, stop):
    """`topgimbal proxy` in its own process between a socket client and a socket 'camera'; what it
    prints, logs and captures in batches is all there after SIGTERM or Ctrl-C."""
    camera = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    camera.bind(("127.0.0.1", 0))
    camera.settimeout(10)
    argv = [sys.executable, "-m", "topgimbal.cli.main", "proxy", "--listen", "udp://127.0.0.1:0"]
    argv += ["--to", f"udp://127.0.0.1:{camera.getsockname()[1]}", "--log", str(tmp_path / "p.jsonl")]
    argv += ["--pcap", str(tmp_path / "p.pcap")]
    argv += ["--json"] if as_json else []
    proc = subprocess.Popen(argv, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    client = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    client.settimeout(10)
    try:
        assert proc.stderr is not None
        started = proc.stderr.readline()
        port = int(re.search(r"udp://127\.0\.0\.1:(\d+) ->", started).group(1))  # type: ignore[union-attr]
        client.sendto(PTZ, ("127.0.0.1", port))
        data, proxy_side = camera.recvfrom(100)
        assert data == PTZ
        camera.sendto(GAC + b"junk", proxy_side)
        assert client.recv(100) == GAC + b"junk"
    finally:
        client.close()
        camera.close()
        proc.send_signal(stop)
        out, err = proc.communicate(timeout=60)  # a bound on a hang (10 s ran out at load 50)
    lines = out.splitlines()
    assert len(lines) == 3, out
    if as_json:
        recs = [json.loads(x) for x in lines]
        assert set(RECORD_KEYS) <= set(recs[0]) and {"time", "dir", "client"} <= set(recs[0])
        assert [(r["id"], r["dir"], r["ok"]) for r in recs] == [
            ("PTZ", "out", True),
            ("GAC", "in", True),
            (None, "in", False),
        ]
        assert recs[1]["fields"]["pitch_deg"] == -47.74
    else:
        assert " -> udp 127.0.0.1:" in lines[0] and "PTZ gimbal_control action=stop" in lines[0]
        assert " <- " in lines[1] and "GAC attitude yaw_deg=-2.02 pitch_deg=-47.74 roll_deg=0.72" in lines[1]
        assert "! garbage" in lines[2] and "junk" in lines[2]
    assert '"frames_out": 1, "frames_in": 1' in err
    assert len((tmp_path / "p.jsonl").read_text().splitlines()) == 3  # header + 2 frames
    assert sum(isinstance(r, CaptureRecord) for r in read_capture(tmp_path / "p.pcap")) == 2


def test_the_live_json_line_reuses_the_proxys_decoding(monkeypatch):
    """`proxy --json` prints decode --json's record for every form of the catalog without decoding
    the frame again: the Message the proxy decoded is passed along."""
    from topgimbal.cli import protocol_cmds, wire_cmds
    from topgimbal.protocol import DIALECT_NAMES, Frame, FrameParser, decode_any, get_dialect
    from topgimbal.wire.proxy import ProxyEvent

    from .forms import form_frames

    cases = [(f.frame, get_dialect(n)) for n in DIALECT_NAMES for f in form_frames(get_dialect(n))]
    c12_version = FrameParser().feed_datagram(b"#tpDU3rVER0105025A")  # a recovered length: an anomaly
    cases += [(x, get_dialect("skydroid")) for x in c12_version if isinstance(x, Frame)]
    wanted = [protocol_cmds.decode_line(frame.to_bytes().hex(), as_hex=True, dialect=d) for frame, d in cases]
    assert any(w["anomaly"] for w in wanted)

    def no_second_decoding(*args: object, **kwargs: object) -> None:
        raise AssertionError("the frame was decoded again")

    from topgimbal.protocol import decoded

    monkeypatch.setattr(decoded, "decode_with", no_second_decoding)
    for (frame, d), want in zip(cases, wanted, strict=True):
        msg = decode_any(frame, prefer=d)
        event = ProxyEvent(12.5, "in", "udp 127.0.0.1:1", frame, get_dialect(msg.dialect or d.name), msg)
        line = json.loads(wire_cmds._live_line(event, as_json=True))
        assert {k: line[k] for k in RECORD_KEYS} == want
        assert (line["time"], line["dir"], line["client"]) == (12.5, "in", "udp 127.0.0.1:1")


def test_decode_pcap_streams_through_a_bounded_window(tmp_path, capsys, monkeypatch):
    """Issue 28: `decode --pcap` holds at most REORDER_WINDOW records (it used to hold them all to
    sort): disorder within the window is sorted, a record further out of place prints where it falls."""
    from topgimbal.cli import wire_cmds

    path = tmp_path / "w.pcap"
    with CaptureWriter(path) as w:
        for ts in (10.0, 12.0, 11.0, 13.0, 14.0, 15.0, 1.0):  # 11.0: one late; 1.0: far out of place
            w.udp(HOST, SKY, PTZ, ts=ts)
    held: list[int] = []
    real_push = wire_cmds.heapq.heappush

    def push(heap, item):
        real_push(heap, item)
        held.append(len(heap))

    monkeypatch.setattr(wire_cmds, "REORDER_WINDOW", 2)
    monkeypatch.setattr(wire_cmds.heapq, "heappush", push)
    assert main(["decode", "--pcap", str(path), "--json"]) == 0
    times = [json.loads(x)["time"] for x in capsys.readouterr().out.splitlines()]
    assert times == [10.0, 11.0, 12.0, 13.0, 1.0, 14.0, 15.0]
    assert max(held) == 3  # the window plus the one just read, never the whole capture
