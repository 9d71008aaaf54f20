"""Scripted conversations over real loopback sockets (ephemeral ports) and a pty pair."""

from __future__ import annotations

import asyncio
import os
import termios

import pytest

from topgimbal.protocol import Frame, FrameParser, get_dialect
from topgimbal.sim import BackgroundSimulator, Simulator
from topgimbal.sim.servers import configure_tty

from .conftest import LOOP, UdpClient, raw, req

pytestmark = [pytest.mark.loopback, pytest.mark.integration]


async def test_c12_over_udp_conversation_and_replies_to_each_sender() -> None:
    async with Simulator("C12", listen={"udp": [(LOOP, 0)]}) as sim:
        assert sim.url.startswith("udp://127.0.0.1:") and not sim.url.endswith(":0")
        a, b = UdpClient(sim.addresses["udp"][0]), UdpClient(sim.addresses["udp"][0])
        try:
            [echo] = await a.request(req("C12", "GAY", yaw_deg=20.0, speed_deg_s=9.9))
            assert (echo.ident, echo.src, echo.dst) == ("GAY", "G", "U")
            [rec] = await b.request(req("C12", "REC", read=True))
            assert rec.ident == "REC" and rec.data == b"00"
            assert await a.collect(wait=0.1) == []  # b's answer went to b only
            [err] = await a.request(raw("XYZ"))
            assert err.ident == "ERE"
            # attitude stream to the host that asked, at its rate
            await a.request(req("C12", "GAA", rate_hz=50))
            # ten frames, however long a loaded machine takes (10 s: a bound on a hang; the rate is bench/'s)
            got = await a.collect(wait=10, count=10)
            assert len(got) >= 10 and {f.ident for f in got} == {"GAC"}
            assert await b.collect(wait=0.1) == []
            assert [f.ident for f in sim.received] == ["GAY", "REC", "XYZ", "GAA"]
            assert sim.gimbal.yaw_deg > 0
        finally:
            a.close()
            b.close()


async def test_c10_listens_on_udp_and_tcp_and_answers_on_the_connection() -> None:
    async with Simulator("C10", listen={"udp": [(LOOP, 0), (LOOP, 0)], "tcp": [(LOOP, 0)]}) as sim:
        assert [k for k, _ in sim.endpoints] == ["udp", "udp", "tcp"]
        host, port = sim.addresses["tcp"][0]
        reader, writer = await asyncio.open_connection(host, port)
        try:
            msg = req("C10", "REC", action="start")
            writer.write(msg[:5])  # a byte stream may split frames anywhere
            await writer.drain()
            await asyncio.sleep(0.05)
            writer.write(msg[5:] + req("C10", "REC", read=True))
            await writer.drain()
            parser, out = FrameParser(), []
            while len(out) < 2:
                out += [f for f in parser.feed(await asyncio.wait_for(reader.read(100), 2)) if isinstance(f, Frame)]
            assert [f.ident for f in out] == ["REC", "REC"] and out[1].data == b"01"
            assert sim.camera.recording
        finally:
            writer.close()


async def test_c20_over_tcp_with_attitude_stream_dropped_on_disconnect() -> None:
    async with Simulator("C20", listen={"tcp": [(LOOP, 0)]}) as sim:
        reader, writer = await asyncio.open_connection(*sim.addresses["tcp"][0])
        writer.write(req("C20", "GAA", rate_hz=20))
        await writer.drain()
        data = b""
        while data.count(b"GAC") < 3:
            data += await asyncio.wait_for(reader.read(1000), 2)
        assert len(sim.device.streams) == 1
        writer.close()
        await writer.wait_closed()
        for _ in range(50):
            if not sim.device.streams:
                break
            await asyncio.sleep(0.02)
        assert sim.device.streams == {}


async def test_sip_over_a_pty_at_115200_8n1() -> None:
    async with Simulator("SIP", listen={"serial": ["pty"]}) as sim:
        kind, url = sim.endpoints[0]
        assert kind == "serial" and url.endswith("?baud=115200")
        path = url.removeprefix("serial://").split("?")[0]
        fd = os.open(path, os.O_RDWR | os.O_NOCTTY | os.O_NONBLOCK)
        try:
            configure_tty(fd)
            assert termios.tcgetattr(fd)[4] == termios.B115200
            loop = asyncio.get_running_loop()
            got: asyncio.Queue[bytes] = asyncio.Queue()
            loop.add_reader(fd, lambda: got.put_nowait(os.read(fd, 1000)))
            os.write(fd, raw("VSN", src="U", dst="D", rw="r"))
            parser, out = FrameParser(), []
            while not out:
                out += [f for f in parser.feed_datagram(await asyncio.wait_for(got.get(), 2)) if isinstance(f, Frame)]
            assert (out[0].ident, out[0].dst) == ("VSN", "U")
            loop.remove_reader(fd)
        finally:
            os.close(fd)


def test_documented_endpoints_per_model() -> None:
    assert Simulator("C12").documented_listen() == {"udp": [(LOOP, 5000)], "tcp": [], "serial": []}
    assert Simulator("C10").documented_listen()["udp"] == [(LOOP, 5000), (LOOP, 9002)]
    assert Simulator("C20").documented_listen() == {"udp": [], "tcp": [(LOOP, 5000)], "serial": []}
    assert Simulator("SIP").documented_listen() == {"udp": [(LOOP, 9003)], "tcp": [], "serial": ["pty"]}


def test_background_simulator_for_sync_code() -> None:
    import socket

    with BackgroundSimulator("SIP", seed=1, listen={"udp": [(LOOP, 0)]}) as bg:
        assert bg.url.startswith("udp://127.0.0.1:")
        host, port = bg.sim.addresses["udp"][0]
        with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as s:
            s.bind((LOOP, 0))
            s.settimeout(2)
            s.sendto(req("SIP", "REC", action="start"), (host, port))
            reply = s.recv(100)
        assert b"REC11" in reply
        assert bg.call(lambda sim: sim.camera.recording) is True
        assert bg.call(lambda sim: sim.camera.record_index) == 1


@pytest.mark.external
async def test_ardupilot_topotek_driver_conversation_over_tcp() -> None:
    """What ArduPilot's TOPOTEK driver sends over a byte stream, and reads back (seeds README)."""
    d = get_dialect("topotek")
    async with Simulator("SIP", listen={"tcp": [(LOOP, 0)]}, topotek_stream_hz=50) as sim:
        reader, writer = await asyncio.open_connection(*sim.addresses["tcp"][0])
        parser = FrameParser()
        inbox: list[Frame] = []

        async def until(pred: object, timeout: float = 30.0) -> Frame:  # a bound on a hang
            async def loop() -> Frame:
                while True:
                    for i, f in enumerate(inbox):
                        if pred(f):  # type: ignore[operator]
                            return inbox.pop(i)
                    inbox.extend(f for f in parser.feed(await reader.read(4096)) if isinstance(f, Frame))

            return await asyncio.wait_for(loop(), timeout)

        def send(ident: str, read: bool = False, **v: object) -> None:
            writer.write(d.encode(ident, read=read, src="U", **v).to_bytes())

        try:
            send("GIA", state="on")
            send("VSN", read=True)
            send("PA2", read=True)
            send("SDC", read=True, which="remaining")
            send("TRC", read=True)
            from datetime import datetime

            send("UTC", time=datetime(2026, 1, 2, 3, 4, 5))
            send("LAT", lat_deg=-33.5)
            send("LON", lon_deg=151.2)
            send("ALT", alt_m=120.0)
            send("AZI", azimuth_deg=90.0)
            send("YPR", yaw_rate_deg_s=0.0, pitch_rate_deg_s=30.0, roll_rate_deg_s=0.0)  # pitch down on the wire
            await writer.drain()
            gia = await until(lambda f: f.ident == "GIA" and len(f.data) >= 12)
            assert gia.dst == "U" and len(gia.data[:12]) == 12
            assert (await until(lambda f: f.ident == "VSN")).data in (b"1.2.3", b"123")
            assert (await until(lambda f: f.ident == "PA2")).data == b"SIP"
            assert (await until(lambda f: f.ident == "SDC")).data.isalnum()
            assert (await until(lambda f: f.ident == "TRC")).data[1:2] == b"0"
            # the rate command took the camera down (waited for on the wire, not for 0.5 s of clock)
            await until(lambda f: f.ident == "GIA" and len(f.data) >= 12 and d.decode(f).fields["pitch_deg"] > 5)  # type: ignore[index]
            assert sim.gimbal.pitch_deg < -5  # camera went down
            send("GIP", pitch_deg=45.0, speed_deg_s=9.9)
            send("GAY", yaw_deg=0.0, speed_deg_s=9.9)
            await writer.drain()
            # the camera down: a GIA says so down-positive (at 50 Hz on a loaded machine the frames
            # back up in the socket: the next one read may be from before the move, so wait for it)
            last = await until(lambda f: f.ident == "GIA" and len(f.data) >= 12 and d.decode(f).fields["pitch_deg"] > 0)  # type: ignore[index]
            wire_pitch = d.decode(last).fields["pitch_deg"]  # type: ignore[index]
            assert wire_pitch > 0 and sim.gimbal.pitch_deg < 0  # down-positive on the wire
            assert sim.device.position.lat_deg == pytest.approx(-33.5)
        finally:
            writer.close()


@pytest.mark.parametrize(
    ("model", "control", "query", "unsupported"),
    [
        ("C10", ("PTZ", {"action": "lock"}), "GAC", "SDC"),
        ("C10Pro", ("REC", {"action": "start"}), "EXT", "IMG"),
        ("C12", ("IMG", {"palette": "rainbow"}), "UID", "TSM"),
        ("C13", ("TIB", {"brightness": 80}), "TGM", "GOT"),  # C13 motion: public reports (errata E28)
        ("C20", ("GSY", {"yaw_rate_deg_s": 5.0}), "GAC", "REC"),
        ("SIP", ("GIY", {"yaw_deg": -30.0, "speed_deg_s": 5.0}), "GMS", "SLR"),
    ],
)
async def test_scripted_udp_conversation_per_model(
    model: str, control: tuple[str, dict[str, object]], query: str, unsupported: str
) -> None:
    async with Simulator(model, listen={"udp": [(LOOP, 0)]}) as sim:
        c = UdpClient(sim.addresses["udp"][0])
        try:
            ident, values = control
            sent = req(model, ident, **values)
            [echo] = await c.request(sent)
            assert echo.to_bytes() == frames_of(sent).swapped().to_bytes()
            [answer] = await c.request(req(model, query, read=True))
            assert answer.ident == query and answer.rw == "r" and sim.dialect.decode(answer).fields is not None
            [err] = await c.request(raw(unsupported, src=sim.device.model.host_address, dst="D", rw="r"))
            assert err.ident == "ERE"
        finally:
            c.close()


def frames_of(data: bytes) -> Frame:
    [f] = [x for x in FrameParser().feed(data) if isinstance(x, Frame)]
    return f
