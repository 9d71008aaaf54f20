"""The proxy between the SDK (or raw sockets) and the simulator, on loopback: it forwards every
byte unchanged both ways over UDP, TCP and serial, publishes each frame to subscribers, writes a
pcap that tshark decodes like the Python decoder and the client's JSONL traffic log, and keeps its
limits."""

from __future__ import annotations

import asyncio
import contextlib
import json
import os
import socket
import sys
import tty
from pathlib import Path
from typing import Any

import pytest

import topgimbal
from topgimbal.client.traffic import read_log
from topgimbal.protocol import Frame, FrameParser, decode_any, get_dialect, get_model
from topgimbal.sim import Simulator
from topgimbal.wire import CaptureRecord, read_capture
from topgimbal.wire import proxy as proxy_module
from topgimbal.wire import watcher as watcher_module
from topgimbal.wire.capture import WireFrame, frames_in_capture
from topgimbal.wire.offload import WatcherProcess
from topgimbal.wire.proxy import Proxy, ProxyError, ProxyEvent
from waiting import until

from .tshark import top_layers, values

pytestmark = [pytest.mark.external, pytest.mark.integration]

PTZ = b"#TPUG2wPTZ006A"


async def _sim(model: str, **listen: Any) -> Simulator:
    sim = Simulator(model, seed=7)
    await sim.start(**listen)
    return sim


def _url(sim: Simulator, kind: str) -> str:
    return dict(sim.endpoints)[kind]


async def _echo_device(seen: list[bytes] | None = None, reverse: bool = False) -> tuple[Any, int]:
    """A raw UDP 'camera' on loopback that sends every datagram back (reversed if asked)."""

    class Echo(asyncio.DatagramProtocol):
        def connection_made(self, transport: Any) -> None:
            self.t = transport

        def datagram_received(self, data: bytes, addr: Any) -> None:
            if seen is not None:
                seen.append(data)
            self.t.sendto(data[::-1] if reverse else data, addr)

    dev, _ = await asyncio.get_running_loop().create_datagram_endpoint(Echo, local_addr=("127.0.0.1", 0))
    return dev, dev.get_extra_info("sockname")[1]


async def test_sdk_through_a_udp_proxy(tmp_path, dissector):
    sim = await _sim("SIP", udp=[("127.0.0.1", 0)])
    pcap, log = tmp_path / "sip.pcap", tmp_path / "sip.jsonl"
    proxy = Proxy("udp://127.0.0.1:0", _url(sim, "udp"), model="SIP", pcap=pcap, log_path=log)
    events: list[ProxyEvent] = []
    proxy.subscribe(events.append)
    try:
        await proxy.start()
        async with topgimbal.connect(proxy.url, model="SIP", timeout_s=2.0) as cam:
            assert await cam.version()
            await cam.set_angles(yaw_deg=20, pitch_deg=-30)
            await cam.photo()
            att = await cam.get_attitude()
            assert att is not None
    finally:
        await proxy.stop()
        await sim.stop()
    frames = [e for e in events if isinstance(e.item, Frame)]
    assert {e.direction for e in frames} == {"out", "in"}
    assert all(e.dialect is not None and e.dialect.name == "topotek" for e in frames)
    assert proxy.stats.frames_out + proxy.stats.frames_in == len(frames)
    assert any(e.message and e.message.spec and e.message.spec.ident == "CAP" for e in frames)

    # the traffic log: the client SDK's own reader reads every frame, in order
    header = json.loads(log.read_text().splitlines()[0])
    assert header["topgimbal_log"] == 1 and header["dialect"] == "topotek" and header["model"] == "SIP"
    logged = list(read_log(log))
    assert [(r.direction, r.frame) for r in logged] == [(e.direction, e.item) for e in frames]

    # the pcap: our reader, and tshark with the dissector, see exactly those frames
    in_pcap = [x for x in frames_in_capture(pcap) if isinstance(x, WireFrame)]
    assert [x.item for x in in_pcap] == [e.item for e in frames]
    packets = top_layers(dissector, pcap, "-o", "top.model:SIP")  # what the proxy was told
    shown = [f for p in packets for f in p]
    assert len(shown) == len(frames)
    for node, e in zip(shown, frames, strict=True):
        msg = e.message  # the proxy's own decoding of the frame
        assert msg is not None and values(node, "top.id") == [msg.frame.ident]
        assert values(node, "top.dialect") == [msg.dialect]
        for name, value in (msg.to_dict()["fields"] or {}).items():
            got = values(node, f"top.field.{name}")
            if isinstance(value, (int, float)):
                assert got and float(got[0]) == pytest.approx(value), (name, got, value)
            elif value is not None:
                assert got == [value], (name, got, value)


async def test_sdk_through_a_tcp_proxy(tmp_path, dissector):
    sim = await _sim("C20", tcp=[("127.0.0.1", 0)])
    pcap = tmp_path / "c20.pcapng"
    proxy = Proxy("tcp://127.0.0.1:0", _url(sim, "tcp"), pcap=pcap)
    try:
        await proxy.start()
        async with topgimbal.connect(proxy.url, model="C20", timeout_s=2.0) as cam:
            await cam.set_angles(yaw_deg=10, pitch_deg=-5)
            assert await cam.get_attitude() is not None
    finally:
        await proxy.stop()
        await sim.stop()
    assert proxy.stats.frames_out >= 2 and proxy.stats.frames_in >= 2
    ids = [values(f, "top.id")[0] for p in top_layers(dissector, pcap) for f in p]
    assert "GAM" in ids or "GAY" in ids
    assert "GAC" in ids and len(ids) == proxy.stats.frames_out + proxy.stats.frames_in


async def test_bytes_pass_unchanged_with_garbage_and_several_frames(tmp_path):
    """A raw UDP 'device' that echoes: what arrives on each side is exactly what was sent."""
    loop = asyncio.get_running_loop()
    got_device: list[bytes] = []
    dev, port = await _echo_device(got_device, reverse=True)
    events: list[ProxyEvent] = []
    proxy = Proxy("udp://127.0.0.1:0", f"udp://127.0.0.1:{port}")
    proxy.subscribe(events.append)
    await proxy.start()
    client = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    client.setblocking(False)
    payloads = [PTZ + b"\r\n" + PTZ, b"garbage\xff\x00", b"#tpGPCrGACFF36ED5A0048de\r\n"]  # lower-case checksum
    try:
        for p in payloads:
            await loop.sock_sendto(client, p, ("127.0.0.1", proxy.listen_address[1]))  # type: ignore[index]
            reply = await asyncio.wait_for(loop.sock_recv(client, 1024), 2)
            assert reply == p[::-1]
    finally:
        client.close()
        await proxy.stop()
        dev.close()
    assert got_device == payloads
    kinds = [(e.direction, e.item.ident if isinstance(e.item, Frame) else e.item.kind) for e in events]
    assert kinds[:3] == [("out", "PTZ"), ("out", "PTZ"), ("in", "garbage")]  # a reversed frame is garbage
    assert ("out", "garbage") in kinds and ("out", "GAC") in kinds


async def test_each_frame_is_decoded_once_and_the_files_fill_while_running(tmp_path, monkeypatch):
    """The proxy decodes a frame once, as `decode_any` does with its dialect preferred (a model's
    own: the C11 counts rates in 0.5 deg/s; a frame that dialect cannot decode by the other one),
    and the log, every subscriber and the pcap reuse it; the batched pcap and log reach their files
    on the flush timer while the proxy runs, not only at stop."""
    loop = asyncio.get_running_loop()
    dev, port = await _echo_device()
    pcap, log = tmp_path / "c11.pcap", tmp_path / "c11.jsonl"
    proxy = Proxy("udp://127.0.0.1:0", f"udp://127.0.0.1:{port}", model="C11", pcap=pcap, log_path=log)
    events: list[ProxyEvent] = []
    proxy.subscribe(events.append)
    calls = {"decode": 0}
    real_decode = watcher_module.decode_any

    def counting(frame: Frame, prefer: Any = None) -> Any:
        calls["decode"] += 1
        return real_decode(frame, prefer=prefer)

    monkeypatch.setattr(watcher_module, "decode_any", counting)
    c11, _ = get_model("C11")
    rate = c11.encode("GSY", yaw_rate_deg_s=10.0)  # 0x14 steps of 0.5 deg/s
    topotek_only = get_dialect("topotek").encode("GIC", read=True)
    await proxy.start()
    client = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    client.setblocking(False)
    try:
        for frame in (rate, topotek_only):
            await loop.sock_sendto(client, frame.to_bytes(), ("127.0.0.1", proxy.listen_address[1]))  # type: ignore[index]
            await asyncio.wait_for(loop.sock_recv(client, 1024), 2)
        for _ in range(100):  # the flush timer hands them to the files while the proxy runs
            await asyncio.sleep(0.05)
            frames = [r for r in read_capture(pcap) if isinstance(r, CaptureRecord)]
            if len(frames) == 4 and len(list(read_log(log))) == 4:
                break
        assert len(frames) == 4 and len(list(read_log(log))) == 4
    finally:
        client.close()
        await proxy.stop()
        dev.close()
    assert [e.message.fields for e in events if e.item == rate] == [{"yaw_rate_deg_s": 10.0}] * 2  # type: ignore[union-attr]
    assert all(e.dialect is c11 for e in events if e.item == rate)
    assert [(e.dialect.name, e.message.dialect) for e in events if e.item == topotek_only] == [
        ("topotek", "topotek")
    ] * 2  # type: ignore[union-attr]
    for e in events:
        assert e.message == decode_any(e.item, prefer=c11)  # type: ignore[arg-type]
    assert calls["decode"] == 2  # the GIC frames only: C11's own dialect decoded the GSY frames at once
    assert [r.decoded for r in read_log(log)] == [e.message.to_dict() for e in events]  # type: ignore[union-attr]


async def test_stream_client_to_datagram_device_sends_whole_frames(monkeypatch):
    """TCP client, UDP camera: bytes trickling in one at a time reach the camera as whole frames."""
    # What this checks is the framing at frame boundaries, not the silence flush: a loaded machine
    # stretched a 2 ms gap past STREAM_FLUSH_S (50 ms) and the held half frame went out on its own
    # (as it should: that is the flush's job for a peer that stops mid-frame), so the camera never
    # got a whole query. The flush is pushed out of reach here.
    monkeypatch.setattr(proxy_module, "STREAM_FLUSH_S", 60.0)
    sim = await _sim("C12", udp=[("127.0.0.1", 0)])
    proxy = Proxy("tcp://127.0.0.1:0", _url(sim, "udp"))
    await proxy.start()
    try:
        reader, writer = await asyncio.open_connection(*proxy.listen_address)  # type: ignore[misc]
        query = get_dialect("skydroid").encode("GAC", read=True).to_bytes()
        for b in query:
            writer.write(bytes([b]))
            await writer.drain()
            await asyncio.sleep(0.002)
        parser = FrameParser()
        answer: list[Any] = []
        while not answer:
            answer = [f for f in parser.feed(await asyncio.wait_for(reader.read(100), 30)) if isinstance(f, Frame)]
        assert answer[0].ident == "GAC" and len(answer[0].data) == 12
        assert [f.ident for f in sim.received][-1:] == ["GAC"]
        writer.close()
    finally:
        await proxy.stop()
        await sim.stop()


async def test_udp_client_to_serial_camera():
    """Apps on UDP, the camera on its UART (the simulator's pty)."""
    sim = await _sim("SIP", serial=["pty"])
    proxy = Proxy("udp://127.0.0.1:0", _url(sim, "serial"), model="SIP")
    await proxy.start()
    try:
        async with topgimbal.connect(proxy.url, model="SIP", timeout_s=2.0) as cam:
            await cam.set_angles(yaw_deg=5, pitch_deg=5)
            assert await cam.version()
    finally:
        await proxy.stop()
        await sim.stop()
    assert proxy.stats.frames_in >= 2


async def test_serial_ground_station_to_udp_camera(tmp_path):
    """A ground station on a serial line (here a pty the test holds) and the camera on UDP."""
    sim = await _sim("C12", udp=[("127.0.0.1", 0)])
    master, slave = os.openpty()
    tty.setraw(master)
    tty.setraw(slave)
    path = os.ttyname(slave)
    pcap = tmp_path / "serial.pcap"
    proxy = Proxy(f"serial://{path}?baud=115200", _url(sim, "udp"), pcap=pcap)
    await proxy.start()
    loop = asyncio.get_running_loop()
    try:
        query = get_dialect("skydroid").encode("GAC", read=True).to_bytes()
        os.write(master, query[:5])
        await asyncio.sleep(0.01)
        os.write(master, query[5:])
        parser = FrameParser()
        answer: list[Any] = []
        while not answer:
            chunk = await asyncio.wait_for(loop.run_in_executor(None, os.read, master, 100), 2)
            answer = [f for f in parser.feed(chunk) if isinstance(f, Frame)]
        assert answer[0].ident == "GAC"
    finally:
        await proxy.stop()
        await sim.stop()
        os.close(master)
        os.close(slave)
    got = [x for x in frames_in_capture(pcap) if isinstance(x, WireFrame)]
    assert [x.item.ident for x in got] == ["GAC", "GAC"]  # type: ignore[union-attr]
    assert got[0].dst == ("127.0.0.1", int(_url(sim, "udp").rsplit(":", 1)[1]))


async def test_client_limits_and_subscriber_isolation(caplog):
    sim = await _sim("C12", udp=[("127.0.0.1", 0)], tcp=[("127.0.0.1", 0)])
    seen: list[ProxyEvent] = []

    def broken(event: ProxyEvent) -> None:
        raise RuntimeError("a subscriber bug")

    udp = Proxy("udp://127.0.0.1:0", _url(sim, "udp"), max_clients=1)
    udp.subscribe(broken)
    unsubscribe = udp.subscribe(seen.append)
    await udp.start()
    try:
        # no host feeds, no background model check: anything the first client sends while the second
        # one asks takes the one client place back (seen under load: 3 drops instead of 1)
        quiet = {"timeout_s": 2.0, "host_feeds": False, "check_model": False}
        async with topgimbal.connect(udp.url, model="C12", **quiet) as first:
            await first.version()
            async with topgimbal.connect(udp.url, model="C12", **quiet) as second:
                await second.version()  # replaces the first client
            udp.drain()
            assert udp.stats.clients_dropped == 1
        assert udp.stats.subscriber_errors >= 4 and len(seen) >= 4
        unsubscribe()
        n = len(seen)
        async with topgimbal.connect(udp.url, model="C12", timeout_s=2.0) as third:
            await third.version()
        udp.drain()
        assert len(seen) == n
    finally:
        await udp.stop()
    assert "at most 1 client" in caplog.text and "subscriber" in caplog.text

    tcp = Proxy("tcp://127.0.0.1:0", _url(sim, "tcp"), max_clients=1)
    await tcp.start()
    try:
        r1, w1 = await asyncio.open_connection(*tcp.listen_address)  # type: ignore[misc]
        await asyncio.sleep(0.05)
        r2, w2 = await asyncio.open_connection(*tcp.listen_address)  # type: ignore[misc]
        assert await asyncio.wait_for(r2.read(10), 2) == b""  # refused: closed at once
        w1.write(get_dialect("skydroid").encode("GAC", read=True).to_bytes())
        assert (await asyncio.wait_for(r1.read(100), 2)).startswith(b"#TPGUCrGAC")
        w1.close()
        w2.close()
    finally:
        await tcp.stop()
        await sim.stop()


def test_proxy_pcap_is_readable_while_it_is_written(tmp_path):
    """Every packet is flushed as written (a reader sees a whole file at any moment)."""
    from topgimbal.wire import CaptureWriter

    path = tmp_path / "live.pcap"
    w = CaptureWriter(path)
    w.udp(("127.0.0.1", 1), ("127.0.0.1", 5000), PTZ)
    assert [type(r) for r in read_capture(path)] == [CaptureRecord]
    w.close()
    assert Path(path).stat().st_size > 24


async def test_a_tcp_client_that_stops_reading_is_closed(caplog):
    """The camera floods; the client never reads: the proxy drops the client instead of buffering."""
    chunk = b"#TPGUCrGAC00000000000023" * 40_000  # ~1 MB

    async def device(reader: asyncio.StreamReader, writer: asyncio.StreamWriter) -> None:
        with contextlib.suppress(ConnectionError):
            for _ in range(64):  # until the proxy closes this link, at most 64 MB
                writer.write(chunk)
                await writer.drain()
        writer.close()

    server = await asyncio.start_server(device, "127.0.0.1", 0)
    port = server.sockets[0].getsockname()[1]
    proxy = Proxy("tcp://127.0.0.1:0", f"tcp://127.0.0.1:{port}")
    await proxy.start()
    client = socket.socket(socket.AF_INET, socket.SOCK_STREAM)
    client.setsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF, 4096)  # and it never reads
    try:
        client.setblocking(False)
        await asyncio.get_running_loop().sock_connect(client, proxy.listen_address)  # type: ignore[arg-type]
        await asyncio.get_running_loop().sock_sendall(client, b"#TPUG2rGAC0032")
        await until("the unread bytes logged", lambda: "unread bytes" in caplog.text, bound_s=30)
        assert "unread bytes" in caplog.text
        assert proxy.stats.clients == 1
    finally:
        client.close()
        await proxy.stop()
        server.close()


async def _wait_for(text: str, caplog: Any) -> None:
    for _ in range(400):
        if text in caplog.text:
            return
        await asyncio.sleep(0.05)
    raise AssertionError(f"{text!r} never logged: {caplog.text[-2000:]}")


async def test_tcp_clients_that_stop_reading_give_their_slot_back(caplog):
    """A client closed for leaving 64 KiB unread kept its session (close() waits for the unread
    bytes to leave, which they never do), so max_clients such clients locked every other client
    out for good; now it is aborted and its slot is free at once."""
    chunk = b"#TPGUCrGAC00000000000023" * 4_000

    async def device(reader: asyncio.StreamReader, writer: asyncio.StreamWriter) -> None:
        with contextlib.suppress(ConnectionError):
            while True:  # floods every connection, until the proxy closes it
                writer.write(chunk)
                await writer.drain()
        writer.close()

    server = await asyncio.start_server(device, "127.0.0.1", 0)
    port = server.sockets[0].getsockname()[1]
    proxy = Proxy("tcp://127.0.0.1:0", f"tcp://127.0.0.1:{port}", max_clients=1)
    await proxy.start()
    loop = asyncio.get_running_loop()
    stuck = socket.socket(socket.AF_INET, socket.SOCK_STREAM)
    stuck.setsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF, 4096)  # and it never reads
    try:
        stuck.setblocking(False)
        await loop.sock_connect(stuck, proxy.listen_address)  # type: ignore[arg-type]
        await _wait_for("unread bytes", caplog)
        for _ in range(100):
            if not proxy._sessions:
                break
            await asyncio.sleep(0.02)
        assert not proxy._sessions
        reader, writer = await asyncio.open_connection(*proxy.listen_address)  # type: ignore[misc]
        assert (await asyncio.wait_for(reader.readexactly(24), 5)) == chunk[:24]  # served, not refused
        writer.close()
        assert "refusing" not in caplog.text
    finally:
        stuck.close()
        await proxy.stop()
        server.close()


@pytest.mark.parametrize("size", ["one frame", "336 KB"])
async def test_a_tcp_client_is_not_cut_while_its_device_link_opens(caplog, monkeypatch, size):
    """A TCP client sends and closes before the camera link is up. More than 64 KiB: the bytes
    beyond were dropped from the middle of the stream (frames cut); now the client is not read
    until the link opens. Either size: what waited was thrown away when the client closed (a
    command sent by `nc -q0` never arrived); now it is delivered, then the link closed."""
    from topgimbal.wire import sessions as sessions_module  # where a session opens its device link

    release = asyncio.Event()
    real_open = sessions_module.open_transport

    async def slow_open(*args: Any) -> Any:
        await release.wait()
        return await real_open(*args)

    monkeypatch.setattr(sessions_module, "open_transport", slow_open)
    received = bytearray()
    done = asyncio.Event()

    async def device(reader: asyncio.StreamReader, writer: asyncio.StreamWriter) -> None:
        while data := await reader.read(65536):
            received.extend(data)
        done.set()
        writer.close()

    server = await asyncio.start_server(device, "127.0.0.1", 0)
    port = server.sockets[0].getsockname()[1]
    proxy = Proxy("tcp://127.0.0.1:0", f"tcp://127.0.0.1:{port}")
    await proxy.start()
    sent = PTZ if size == "one frame" else (PTZ + b"#TPUG2rGAC0032") * 12_000
    try:
        _reader, writer = await asyncio.open_connection(*proxy.listen_address)  # type: ignore[misc]
        writer.write(sent)
        for _ in range(200):  # until the proxy holds what it may (or, before, dropped the rest)
            if sum(s.queued_bytes for s in proxy._sessions.values()) >= min(len(sent), 64 * 1024):
                break
            if "wait for the device link" in caplog.text:
                break
            await asyncio.sleep(0.02)
        writer.close()
        release.set()
        with contextlib.suppress(asyncio.TimeoutError):  # the camera sees the end of the stream
            await asyncio.wait_for(done.wait(), 10)
        assert len(received) == len(sent) and bytes(received) == sent
        assert "dropping" not in caplog.text
        assert ("not reading this client until it opens" in caplog.text) == (size != "one frame")
    finally:
        release.set()
        await proxy.stop()
        server.close()


async def test_a_flood_of_new_clients_is_logged_once_not_once_per_client(caplog):
    """300 UDP clients (one datagram each, as a port-rotating flood sends) against max_clients=2:
    each replacement was a warning line (a log as long as the flood); now one line per 10 s,
    the clients still replaced, counted, and a client sending now still served."""
    dev, port = await _echo_device()
    proxy = Proxy("udp://127.0.0.1:0", f"udp://127.0.0.1:{port}", max_clients=2)
    await proxy.start()
    socks = []
    try:
        for i in range(300):
            sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
            sock.sendto(b"#TP garbage %d" % i, proxy.listen_address)  # type: ignore[arg-type]
            socks.append(sock)
            if len(socks) > 20:
                socks.pop(0).close()
            if i % 20 == 0:
                await asyncio.sleep(0.01)
        await until("300 clients counted", lambda: proxy.stats.clients, lambda n: n >= 300, bound_s=30)
        assert proxy.stats.clients == 300 and proxy.stats.clients_dropped == 298
        assert caplog.text.count("at most 2 client(s); dropping") == 1
        loop = asyncio.get_running_loop()
        good = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        socks.append(good)
        good.setblocking(False)
        good.connect(proxy.listen_address)  # type: ignore[arg-type]
        good.send(PTZ)
        assert await asyncio.wait_for(loop.sock_recv(good, 100), 5) == PTZ  # the echo camera's answer
        assert len(proxy._sessions) <= 2
    finally:
        for sock in socks:
            sock.close()
        await proxy.stop()
        dev.close()


def test_a_throttled_warning_says_how_many_were_left_out(caplog):
    from topgimbal.wire.sessions import Throttle

    now = [100.0]
    throttle = Throttle(every_s=10.0, clock=lambda: now[0])
    for i in range(5):
        throttle.warning("clients", "proxy: client %d dropped", i)
        throttle.warning("refused", "proxy: refusing %d", i)
    now[0] += 10.0
    throttle.warning("clients", "proxy: client %d dropped", 5)
    lines = [r.getMessage() for r in caplog.records]
    assert lines == [
        "proxy: client 0 dropped",
        "proxy: refusing 0",
        "proxy: client 5 dropped (4 more like it not logged)",
    ]


async def test_stop_does_not_wait_for_a_device_link_that_never_opens(monkeypatch):
    """A client left with bytes for a link still opening; stop() ends that wait, closes it all."""
    from topgimbal.wire import sessions as sessions_module  # where a session opens its device link

    never = asyncio.Event()

    async def hanging_open(*args: Any) -> Any:
        await never.wait()

    monkeypatch.setattr(sessions_module, "open_transport", hanging_open)
    proxy = Proxy("tcp://127.0.0.1:0", "tcp://127.0.0.1:9")
    await proxy.start()
    _reader, writer = await asyncio.open_connection(*proxy.listen_address)  # type: ignore[misc]
    writer.write(PTZ)
    for _ in range(200):
        if any(s.queued for s in proxy._sessions.values()):
            break
        await asyncio.sleep(0.02)
    writer.close()
    for _ in range(200):
        if proxy._closing:
            break
        await asyncio.sleep(0.02)
    assert proxy._closing and not proxy._sessions  # the session ended, and waits to deliver PTZ
    await asyncio.wait_for(proxy.stop(), 30)  # a hang guard, not a timing check
    assert not proxy._closing


async def test_a_tcp_camera_that_stops_reading_ends_the_session(caplog):
    """The camera accepts and never reads while the client sends: the proxy's buffer towards the
    camera grew without bound (51 MB in a probe); now the session ends past 64 KiB, logged."""
    held: list[asyncio.StreamWriter] = []

    async def device(reader: asyncio.StreamReader, writer: asyncio.StreamWriter) -> None:
        held.append(writer)  # never reads

    server = await asyncio.start_server(device, "127.0.0.1", 0)
    port = server.sockets[0].getsockname()[1]
    proxy = Proxy("tcp://127.0.0.1:0", f"tcp://127.0.0.1:{port}")
    await proxy.start()
    try:
        reader, writer = await asyncio.open_connection(*proxy.listen_address)  # type: ignore[misc]
        with contextlib.suppress(ConnectionError, asyncio.TimeoutError):
            for _ in range(200):  # up to 20 MB, until the proxy closes this client
                writer.write(PTZ * 7500)
                await asyncio.wait_for(writer.drain(), 1)
        await _wait_for("the device has", caplog)
        assert "unread bytes; closing this client" in caplog.text
        with contextlib.suppress(ConnectionResetError):  # a reset: what it sent was never read
            assert await asyncio.wait_for(reader.read(), 5) == b""  # the client's connection ended
        writer.close()
    finally:
        await proxy.stop()
        server.close()
        for w in held:
            w.close()


async def test_a_serial_line_slower_than_the_camera_drops_chunks_not_memory(caplog):
    """A UDP camera sending more than the serial line carries (here nobody reads the pty): what
    waits for the line is bounded at 64 KiB, whole chunks dropped beyond it, logged once."""
    burst = PTZ * 70  # ~1 KB per datagram

    class Flood(asyncio.DatagramProtocol):
        def connection_made(self, transport: Any) -> None:
            self.t = transport

        def datagram_received(self, data: bytes, addr: Any) -> None:
            for _ in range(400):  # ~400 KB per query
                self.t.sendto(burst, addr)

    loop = asyncio.get_running_loop()
    dev, _ = await loop.create_datagram_endpoint(Flood, local_addr=("127.0.0.1", 0))
    master, slave = os.openpty()
    tty.setraw(master)
    tty.setraw(slave)
    proxy = Proxy(f"serial://{os.ttyname(slave)}?baud=115200", f"udp://127.0.0.1:{dev.get_extra_info('sockname')[1]}")
    await proxy.start()
    try:
        for _ in range(3):
            os.write(master, PTZ)
            await asyncio.sleep(0.2)
        await _wait_for("unsent bytes; dropping chunks", caplog)
        assert proxy._serial is not None
        unsent = proxy._serial.write_buffer_size  # type: ignore[attr-defined]
        assert 0 < unsent <= 64 * 1024 + len(burst)
        assert caplog.text.count("unsent bytes; dropping chunks") == 1
    finally:
        await proxy.stop()
        dev.close()
        os.close(master)
        os.close(slave)


WATCHER = [sys.executable, "-c", "from topgimbal.cli.wire_cmds import watch_main; watch_main()", "quiet"]


async def test_offloaded_watching_sees_every_frame(tmp_path):
    """With a watcher process the proxy forwards, and the other process captures and logs every
    frame, decoded with the proxy's model; its counters come back at stop."""
    loop = asyncio.get_running_loop()
    dev, port = await _echo_device()
    pcap, log = tmp_path / "off.pcapng", tmp_path / "off.jsonl"
    proxy = Proxy(
        "udp://127.0.0.1:0",
        f"udp://127.0.0.1:{port}",
        model="C11",
        pcap=pcap,
        log_path=log,
        offload=WatcherProcess(WATCHER),
    )
    with pytest.raises(ProxyError, match="watcher process"):
        proxy.subscribe(print)
    await proxy.start()
    client = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    client.setblocking(False)
    rate = get_model("C11")[0].encode("GSY", yaw_rate_deg_s=10.0)
    try:
        for _ in range(50):
            await loop.sock_sendto(client, rate.to_bytes() + b"\r\n", ("127.0.0.1", proxy.listen_address[1]))  # type: ignore[index]
            assert await asyncio.wait_for(loop.sock_recv(client, 1024), 2) == rate.to_bytes() + b"\r\n"
    finally:
        client.close()
        await proxy.stop()
        dev.close()
    size = len(rate.to_bytes()) + 2
    assert (proxy.stats.frames_out, proxy.stats.frames_in, proxy.stats.bytes_out) == (50, 50, 50 * size)
    logged = list(read_log(log))
    assert len(logged) == 100 and all(r.decoded["fields"] == {"yaw_rate_deg_s": 10.0} for r in logged)  # type: ignore[index]
    assert sum(isinstance(r, CaptureRecord) for r in read_capture(pcap)) == 100


async def test_a_watcher_process_that_dies_does_not_stop_forwarding(caplog):
    loop = asyncio.get_running_loop()
    dev, port = await _echo_device()
    dies = WatcherProcess([sys.executable, "-c", "import sys; sys.exit(3)"])
    proxy = Proxy("udp://127.0.0.1:0", f"udp://127.0.0.1:{port}", offload=dies)
    await proxy.start()
    assert dies.proc is not None
    await asyncio.to_thread(dies.proc.wait, 10)
    client = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    client.setblocking(False)
    try:
        for i in range(200):  # enough to fill the pipe if nobody noticed the reader is gone
            payload = PTZ + b"%04d" % i
            await loop.sock_sendto(client, payload, ("127.0.0.1", proxy.listen_address[1]))  # type: ignore[index]
            assert await asyncio.wait_for(loop.sock_recv(client, 1024), 2) == payload
    finally:
        client.close()
        await proxy.stop()
        dev.close()
    assert "watcher process stopped" in caplog.text
    assert proxy.stats.frames_out == 0  # nothing was watched; everything was forwarded
