"""The simulator's servers under abuse (issue 9): dead and silent UDP subscribers, too many peers,
TCP clients that never read. Loopback only, bounded in count; waits poll for an outcome and never
assert on a duration."""

from __future__ import annotations

import asyncio
import logging
import socket
from collections.abc import Callable

import pytest

import waiting
from topgimbal.sim import FakeClock, Simulator
from topgimbal.sim.servers import Limits

from .conftest import LOOP, UdpClient, req

pytestmark = [pytest.mark.loopback, pytest.mark.integration]

GAA_100 = req("C12", "GAA", rate_hz=100)


async def until(pred: Callable[[], bool], timeout_s: float = 5.0) -> bool:
    """Poll `pred` until it holds (the outcome is asserted, not how long it took; tests/waiting.py)."""
    await waiting.until("the simulator's counts", pred, bound_s=timeout_s)
    return True


def udp_socket() -> socket.socket:
    s = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    s.bind((LOOP, 0))
    return s


async def test_closed_udp_subscribers_are_forgotten_by_icmp_and_a_live_one_keeps_its_stream() -> None:
    async with Simulator("C12", listen={"udp": [(LOOP, 0)]}) as sim:
        addr = sim.addresses["udp"][0]
        good = UdpClient(addr)
        dead = [udp_socket() for _ in range(40)]
        try:
            await good.request(GAA_100, wait=0.2)
            for s in dead:
                s.sendto(GAA_100, addr)
            assert await until(lambda: len(sim.device.streams) == 41)
            for s in dead:
                s.close()
            # "port unreachable" for each closed socket: the OS names the address, the peer goes.
            assert await until(lambda: len(sim.device.streams) == 1), sim.server_counts
            assert sim.server_counts["udp_forgotten_unreachable"] == 40
            assert sim.server_counts["udp_forgotten_lease"] == 0
            assert sim.peers["udp"] == 1 and len(sim.device._parsers) == 1
            # The ICMP errors failed some sends meant for the live peer: they were sent again.
            await good.collect(wait=0.05)
            got = await good.collect(wait=10, count=10)  # ten frames however slow the machine (a bound)
            assert len(got) >= 10 and {f.ident for f in got} == {"GAC"}
        finally:
            good.close()
            for s in dead:
                s.close()


async def test_a_silent_udp_subscriber_is_forgotten_after_the_lease_and_an_active_one_kept() -> None:
    clock = FakeClock()
    limits = Limits(udp_lease_s=30.0)
    async with Simulator("C12", clock=clock, limits=limits, listen={"udp": [(LOOP, 0)]}) as sim:
        addr = sim.addresses["udp"][0]
        quiet, chatty = udp_socket(), UdpClient(addr)
        try:
            quiet.sendto(GAA_100, addr)
            await chatty.request(GAA_100)
            assert await until(lambda: len(sim.device.streams) == 2)
            clock.advance(20.0)
            await chatty.request(req("C12", "REC", read=True))  # renews the lease of this peer only
            clock.advance(15.0)  # quiet: 35 s unheard; chatty: 15 s
            assert await until(lambda: len(sim.device.streams) == 1)
            [(peer, ident)] = list(sim.device.streams)
            assert ident == "GAC" and peer.addr == chatty.sock.getsockname()
            assert sim.server_counts["udp_forgotten_lease"] == 1
            clock.advance(31.0)
            assert await until(lambda: not sim.device.streams)
            assert sim.peers["udp"] == 0
        finally:
            quiet.close()
            chatty.close()


async def test_udp_peer_cap_forgets_the_least_recently_heard_and_logs_once(caplog: pytest.LogCaptureFixture) -> None:
    caplog.set_level(logging.WARNING, logger="topgimbal.sim")
    limits = Limits(max_udp_peers=4)
    async with Simulator("C12", limits=limits, listen={"udp": [(LOOP, 0)]}) as sim:
        addr = sim.addresses["udp"][0]
        socks = [udp_socket() for _ in range(30)]
        try:
            for s in socks:
                s.sendto(GAA_100, addr)
            assert await until(lambda: sim.server_counts.get("udp_forgotten_cap") == 26)
            kept = {p.addr for p, _ in sim.device.streams}
            assert kept == {s.getsockname() for s in socks[-4:]}
            assert sim.peers["udp"] == 4 and len(sim.device._parsers) == 4
            lines = [r.getMessage() for r in caplog.records if "--max-udp-peers" in r.getMessage()]
            assert len(lines) == 1 and "4 peers (the limit" in lines[0]
        finally:
            for s in socks:
                s.close()


async def test_tcp_client_cap_closes_the_extra_connection(caplog: pytest.LogCaptureFixture) -> None:
    caplog.set_level(logging.WARNING, logger="topgimbal.sim")
    async with Simulator("C20", limits=Limits(max_tcp_clients=2), listen={"tcp": [(LOOP, 0)]}) as sim:
        host, port = sim.addresses["tcp"][0]
        conns = [await asyncio.open_connection(host, port) for _ in range(3)]
        try:
            assert await until(lambda: sim.server_counts["tcp_refused"] == 1)
            assert sim.peers["tcp"] == 2
            reader, _ = conns[2]
            assert await asyncio.wait_for(reader.read(100), 5) == b""  # closed by the simulator
            r0, w0 = conns[0]
            w0.write(req("C20", "GAA", rate_hz=0, read=False))
            assert b"GAA" in await asyncio.wait_for(r0.read(100), 5)  # the admitted ones still work
            assert any("--max-tcp-clients" in r.getMessage() for r in caplog.records)
        finally:
            for _, w in conns:
                w.close()


async def test_a_tcp_client_that_never_reads_is_dropped_at_the_buffer_limit(caplog: pytest.LogCaptureFixture) -> None:
    caplog.set_level(logging.WARNING, logger="topgimbal.sim")
    limits = Limits(tcp_buffer_bytes=8192, tcp_sndbuf_bytes=4096)
    async with Simulator("C20", limits=limits, listen={"tcp": [(LOOP, 0)]}) as sim:
        host, port = sim.addresses["tcp"][0]
        reader, writer = await asyncio.open_connection(host, port)
        deaf = socket.socket(socket.AF_INET, socket.SOCK_STREAM)
        deaf.setsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF, 4096)
        deaf.connect((host, port))
        deaf.setblocking(False)
        try:
            assert await until(lambda: sim.peers["tcp"] == 2)
            deaf.send(req("C20", "GAA", rate_hz=100))
            flood = req("C20", "GAC", read=True) * 200  # replies outgrow every buffer: nobody reads them
            for _ in range(200):
                try:
                    deaf.send(flood)
                except (BlockingIOError, ConnectionError):
                    break  # the simulator stopped reading this client's requests: its replies backed up
                await asyncio.sleep(0)
            # Then its attitude stream alone fills the rest of the buffer: dropped.
            assert await until(lambda: sim.server_counts["tcp_overflow_dropped"] == 1, timeout_s=30)
            assert await until(lambda: sim.peers["tcp"] == 1)
            # What the simulator held for it never passed the limit plus one frame.
            assert 8192 < sim._tcp[0].max_unsent <= 8192 + 64
            assert any("does not read: dropped" in r.getMessage() for r in caplog.records)
            writer.write(req("C20", "GAC", read=True))
            assert b"GAC" in await asyncio.wait_for(reader.read(100), 5)  # the reader is unaffected
        finally:
            deaf.close()
            writer.close()


async def test_the_stream_of_a_forgotten_tcp_client_goes_and_memory_stays_bounded() -> None:
    """After 200 connect/subscribe/close cycles the simulator holds nothing for any of them."""
    async with Simulator("C20", listen={"tcp": [(LOOP, 0)]}) as sim:
        host, port = sim.addresses["tcp"][0]
        for _ in range(200):
            _, w = await asyncio.open_connection(host, port)
            w.write(req("C20", "GAA", rate_hz=100))
            await w.drain()
            w.close()
        assert await until(lambda: sim.peers["tcp"] == 0 and not sim.device.streams)
        assert len(sim.device._parsers) == 0
