"""Issue 12, console side: what the console recorded (its traffic, in and out, with timestamps)
downloads as a pcap (`GET /api/traffic.pcap`), bounded, that `topgimbal.wire` reads back frame for
frame and tshark decodes with the dissector generated from this branch's catalog."""

from __future__ import annotations

import asyncio
from pathlib import Path
from typing import Any

import aiohttp
import pytest

from topgimbal.console import ConsoleServer
from topgimbal.console.capture import HOST_PORT, Link, Recorder, link_for
from topgimbal.console.watch import client_endpoint
from topgimbal.protocol import Frame, get_model
from topgimbal.wire import WireFrame, frames_in_capture
from wire.tshark import run_tshark

pytestmark = [pytest.mark.external, pytest.mark.integration]


# The committed dissector (`topgimbal dissector`, kept current by tests/wire): these tests read
# only what any version of it shows, the frame's header (identifier, dialect), never field codecs.
DISSECTOR = Path(__file__).resolve().parents[2] / "contrib" / "wireshark" / "topgimbal.lua"


@pytest.fixture(scope="module")
def dissector() -> Path:
    assert DISSECTOR.exists(), f"{DISSECTOR} is missing: `make docs` writes it"
    return DISSECTOR


# -- the recorder and the addresses -------------------------------------------------------------


def test_the_recorder_keeps_the_newest_frames_within_its_bounds() -> None:
    r = Recorder(max_frames=5, max_bytes=1000)
    for i in range(8):
        r.add(float(i), "out" if i % 2 else "in", b"#TPUD2rVER00%02d" % i)
    assert len(r) == 5 and r.total == 8 and r.forgotten == 3
    assert [f.t for f in r.frames()] == [3.0, 4.0, 5.0, 6.0, 7.0]
    small = Recorder(max_frames=100, max_bytes=25)
    for i in range(4):
        small.add(float(i), "in", b"0123456789")
    assert [f.t for f in small.frames()] == [2.0, 3.0] and small.bytes == 20
    assert small.describe()["max_bytes"] == 25


def test_addresses_in_the_pcap() -> None:
    _, c12 = get_model("C12")
    _, sip = get_model("SIP")
    assert link_for("udp://127.0.0.1:5000", c12) == Link("udp", ("127.0.0.1", HOST_PORT), ("127.0.0.1", 5000))
    # TOPOTEK's documented client port, so Wireshark's dissector picks the dialect
    assert link_for("udp://[::1]:42000", sip) == Link("udp", ("::1", 9004), ("::1", 42000))
    assert link_for("tcp://127.0.0.1:5000", c12).transport == "tcp"
    serial = link_for("serial:///dev/ttyUSB0?baud=115200", c12)
    assert serial.transport == "udp" and serial.device[1] == next(e.port for e in c12.endpoints if e.kind == "udp")
    assert link_for("udp://camera.local:5000", c12).device == ("127.0.0.1", 5000)  # a name: loopback
    assert client_endpoint("udp 127.0.0.1:53012") == ("127.0.0.1", 53012)
    assert client_endpoint("tcp [::1]:5000") == ("::1", 5000)
    assert client_endpoint("serial /dev/pts/3") is None


# -- the download -------------------------------------------------------------------------------


async def _op(ws: aiohttp.ClientWebSocketResponse, ref: int, op: str, **args: Any) -> dict[str, Any]:
    await ws.send_json({"op": op, "ref": ref, **args})
    while True:
        msg = await ws.receive_json(timeout=30)
        if msg.get("ref") == ref:
            assert msg["type"] == "ack", msg
            return msg  # type: ignore[no-any-return]


async def _download(srv: ConsoleServer, tmp_path: Path, name: str, **headers: str) -> tuple[Path, Any]:
    async with aiohttp.ClientSession() as http, http.get(srv.base_url + "api/traffic.pcap", headers=headers) as r:
        assert r.status == 200, await r.text()
        path = tmp_path / name
        path.write_bytes(await r.read())
        return path, r.headers


async def test_the_pcap_holds_what_the_console_recorded(tmp_path: Path, dissector: Path) -> None:
    async with ConsoleServer(sim_model="C12", port=0) as srv, aiohttp.ClientSession() as http:
        assert srv.hub is not None and srv.sim is not None
        ws = await http.ws_connect(srv.base_url + "ws")
        await _op(ws, 1, "version")
        await _op(ws, 2, "photo")
        await _op(ws, 3, "request", id="IMG", values={"palette": "black_hot"})
        await asyncio.sleep(0.3)
        recorded = srv.hub.recorder.frames()  # the download is taken after: it holds at least these
        path, headers = await _download(srv, tmp_path, "c12.pcap")
        assert headers["Content-Type"] == "application/vnd.tcpdump.pcap"
        assert 'filename="topgimbal-C12-' in headers["Content-Disposition"]

    sim_port = int(srv.url.rsplit(":", 1)[1]) if srv.url else 0
    # (the C12 answers VER with a wrong length character: the reader notes it, then gives the frame)
    frames = [f for f in frames_in_capture(path) if isinstance(f, WireFrame) and isinstance(f.item, Frame)]
    assert len(frames) >= len(recorded) > 10
    for rec, wf in zip(recorded, frames, strict=False):
        assert isinstance(wf.item, Frame)  # (for mypy)
        assert wf.item.to_bytes() == rec.data
        assert wf.ts == pytest.approx(rec.t, abs=1e-6)
        out = rec.direction == "out"
        assert (wf.dst if out else wf.src) == ("127.0.0.1", sim_port)
        assert (wf.src if out else wf.dst) == ("127.0.0.1", HOST_PORT)
    idents = [wf.item.ident for wf in frames if isinstance(wf.item, Frame)]
    assert {"VER", "CAP", "IMG", "GAC"} <= set(idents)
    directions = {(wf.item.ident, wf.src[1] == sim_port) for wf in frames if isinstance(wf.item, Frame)}
    assert ("CAP", False) in directions and ("CAP", True) in directions  # the photo, sent and echoed

    # tshark on its own: one UDP datagram per frame, between the right ports, holding the frame
    out = run_tshark(None, path, "-T", "fields", "-e", "udp.srcport", "-e", "udp.dstport", "-e", "data.data")
    rows = [line.split("\t") for line in out.splitlines()]
    assert [bytes.fromhex(r[2]) for r in rows] == [wf.item.to_bytes() for wf in frames if isinstance(wf.item, Frame)]
    assert all({r[0], r[1]} == {str(sim_port), str(HOST_PORT)} for r in rows)
    # and with the dissector: a TOP frame in every packet, with the same identifiers
    out = run_tshark(dissector, path, "-T", "fields", "-e", "top.id")
    assert out.split() == idents


async def test_a_topotek_capture_is_decoded_as_topotek(tmp_path: Path, dissector: Path) -> None:
    async with ConsoleServer(sim_model="SIP", port=0) as srv, aiohttp.ClientSession() as http:
        ws = await http.ws_connect(srv.base_url + "ws")
        await _op(ws, 1, "version")
        await asyncio.sleep(0.3)
        path, _ = await _download(srv, tmp_path, "sip.pcap")
    out = run_tshark(dissector, path, "-T", "fields", "-e", "top.dialect", "-e", "top.id")
    rows = [line.split("\t") for line in out.splitlines() if line.strip()]
    assert rows and {r[0] for r in rows} == {"topotek"}
    assert "VSN" in {r[1] for r in rows}


async def test_the_download_is_bounded(tmp_path: Path) -> None:
    async with ConsoleServer(sim_model="C12", port=0) as srv:
        assert srv.hub is not None
        srv.hub.recorder.max_frames = 20  # the attitude stream alone passes that in a second
        await asyncio.sleep(1.5)
        path, headers = await _download(srv, tmp_path, "bounded.pcap")
        assert srv.hub.recorder.forgotten > 0
    frames = [f for f in frames_in_capture(path) if isinstance(f, WireFrame) and isinstance(f.item, Frame)]
    assert len(frames) == 20 == int(headers["X-Topgimbal-Frames"])


async def test_the_download_needs_the_token_and_a_good_host() -> None:
    async with ConsoleServer(sim_model="C12", port=0, token="s3cret") as srv, aiohttp.ClientSession() as http:
        url = srv.base_url + "api/traffic.pcap"
        async with http.get(url) as r:
            assert r.status == 401
        async with http.get(url, headers={"X-Topgimbal-Token": "s3cret"}) as r:
            assert r.status == 200 and (await r.read())[:4] == b"\xd4\xc3\xb2\xa1"  # pcap, little-endian
        async with http.get(url + "?token=s3cret", headers={"Host": f"evil.example:{srv.bound_port}"}) as r:
            assert r.status == 421  # DNS rebinding: refused before the token is looked at
