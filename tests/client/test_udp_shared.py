"""`udp://HOST:PORT?socket=shared` (transport/udp_shared.py): many cameras on one socket of the
event loop, each camera's datagrams to its own client only, strangers dropped and counted, and the
same guarantees a connected socket gives; `topgimbal zenoh` serves its UDP cameras this way."""

from __future__ import annotations

import asyncio
import socket
from collections.abc import AsyncIterator

import pytest

import topgimbal
from topgimbal.errors import TransportError
from topgimbal.fleet.camera import served_url
from topgimbal.sim.simulator import Simulator
from topgimbal.transport.udp import UdpTransport
from topgimbal.transport.udp_shared import SharedUdpSocket

pytestmark = pytest.mark.loopback


@pytest.fixture
async def sims() -> AsyncIterator[list[Simulator]]:
    made = [await Simulator("C12", seed=i).start(udp=["127.0.0.1:0"]) for i in range(3)]
    # three cameras that point three different ways: a reply handed to the wrong client shows
    for sim, (yaw, pitch) in zip(made, [(30.0, -10.0), (-60.0, 5.0), (90.0, -45.0)], strict=True):
        sim.gimbal.axis("yaw").pos = sim.gimbal.axis("yaw").target = yaw
        sim.gimbal.axis("pitch").pos = sim.gimbal.axis("pitch").target = pitch
    yield made
    for sim in made:
        await sim.stop()


def _transport(cam: topgimbal.AsyncClient) -> UdpTransport:
    t = cam._transport
    assert isinstance(t, UdpTransport)
    return t


async def test_cameras_share_one_socket_and_each_gets_only_its_own_replies(sims: list[Simulator]) -> None:
    cams = [await topgimbal.connect(f"{s.url}?socket=shared", model="C12") for s in sims]
    try:
        shared = {id(_transport(c)._shared) for c in cams}
        assert len(shared) == 1 and None not in {_transport(c)._shared for c in cams}
        sock = _transport(cams[0])._shared
        assert isinstance(sock, SharedUdpSocket) and len(sock.routes) == 3
        for _ in range(5):  # interleaved: every read must come back with its own camera's angles
            for cam, (yaw, pitch) in zip(cams, [(30.0, -10.0), (-60.0, 5.0), (90.0, -45.0)], strict=True):
                att = await cam.get_attitude()
                assert (round(att.yaw_deg), round(att.pitch_deg)) == (yaw, pitch)
        # each simulator heard one peer: the shared socket's port
        port = sock.local_address[1]
        for sim in sims:
            assert [addr[1] for u in sim._udp for addr in u.peers] == [port]
        assert sock.strangers == 0 and sock.received >= 15
    finally:
        for cam in cams:
            await cam.close()
    assert sock.closed  # closed with its last camera


async def test_a_stranger_is_dropped_and_counted_and_the_camera_goes_on(sims: list[Simulator]) -> None:
    cam = await topgimbal.connect(f"{sims[0].url}?socket=shared", model="C12")
    try:
        shared = _transport(cam)._shared
        assert shared is not None
        port = shared.local_address[1]
        # a frame that would pass for the camera's answer, from another address
        with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as stranger:
            stranger.sendto(b"#TPGUCrGAC00000000000023", ("127.0.0.1", port))
        att = await cam.get_attitude()
        assert round(att.yaw_deg) == 30
        assert shared.strangers == 1
    finally:
        await cam.close()


async def test_two_clients_of_one_camera_do_not_share_a_route(sims: list[Simulator]) -> None:
    a = await topgimbal.connect(f"{sims[1].url}?socket=shared", model="C12")
    b = await topgimbal.connect(f"{sims[1].url}?socket=shared", model="C12")
    try:
        assert _transport(a)._shared is not None
        assert _transport(b)._shared is None  # whose reply would it be: the second has its own socket
        for cam in (a, b):
            assert round((await cam.get_attitude()).yaw_deg) == -60
    finally:
        await a.close()
        await b.close()


@pytest.mark.parametrize(
    ("query", "said"),
    [("socket=both", "socket='both': expected one of own, shared"),
     ("socket=shared&local_port=0", "socket=shared and local_port exclude each other")],
)  # fmt: skip
async def test_a_bad_socket_choice_is_refused(sims: list[Simulator], query: str, said: str) -> None:
    with pytest.raises(TransportError, match=said.replace("(", r"\(")):
        await topgimbal.connect(f"{sims[0].url}?{query}", model="C12")


def test_the_fleet_server_shares_unless_the_url_chose() -> None:
    assert served_url("udp://127.0.0.1:5000") == "udp://127.0.0.1:5000?socket=shared"
    assert served_url("udp://127.0.0.1:5000?x=1") == "udp://127.0.0.1:5000?x=1&socket=shared"
    assert served_url("udp://127.0.0.1:5000?socket=own") == "udp://127.0.0.1:5000?socket=own"
    assert served_url("udp://127.0.0.1:5000?local_port=9004") == "udp://127.0.0.1:5000?local_port=9004"
    assert served_url("tcp://127.0.0.1:5000") == "tcp://127.0.0.1:5000"


async def test_the_last_camera_closing_in_its_handler_ends_the_read_cleanly(sims: list[Simulator]) -> None:
    cam = await topgimbal.connect(f"{sims[2].url}?socket=shared", model="C12")
    t = _transport(cam)
    shared, peer = t._shared, t._peer
    assert shared is not None and peer is not None

    def last_one(data: bytes) -> None:  # the handler of the socket's only camera lets it go
        shared.unregister(peer, last_one)

    shared.routes[peer] = last_one
    t.send(b"#TPUG2rGAC0032")  # its answer runs the handler, which closes the socket mid-read
    for _ in range(200):
        if shared.closed:
            break
        await asyncio.sleep(0.01)
    assert shared.closed and shared.read_errors == 0  # no read of a closed socket
    await cam.close()


async def test_datagrams_the_kernel_dropped_are_counted_and_said(caplog: pytest.LogCaptureFixture) -> None:
    """A loop that fell behind by more than the receive buffer loses datagrams in the kernel, where
    no Python code sees them: the socket reads the kernel's count and says it (issue 45)."""
    import logging

    from topgimbal.transport.udp_shared import shared_socket

    camera = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)  # a camera sending faster than we read
    camera.bind(("127.0.0.1", 0))
    got: list[bytes] = []
    shared = shared_socket(socket.AF_INET)
    try:
        assert shared.register(camera.getsockname(), got.append)
        shared.sock.setsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF, 4096)  # the smallest the kernel allows
        rcvbuf = shared.sock.getsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF)
        with caplog.at_level(logging.WARNING, "topgimbal.transport"):
            for _ in range(500):  # no await: the loop is busy elsewhere meanwhile
                camera.sendto(b"#tpUG2wGAC0C00000000000000XX", shared.local_address)
            await asyncio.sleep(0.2)  # now it reads what the buffer kept
        assert 0 < len(got) < 500
        assert shared.kernel_dropped == 500 - len(got)  # every datagram is either read or counted
        assert f"the kernel dropped {shared.kernel_dropped} datagrams from the cameras" in caplog.text
        assert f"its receive buffer ({rcvbuf} bytes) was full" in caplog.text
    finally:
        shared.close()
        camera.close()


@pytest.mark.parametrize("path", ["recvmmsg", "recvfrom_into"])
async def test_both_read_paths_deliver_the_same_datagrams_in_order_and_a_bounded_batch(path: str) -> None:
    """The C path (`_speedups.recv_many`, Linux IPv4) and the pure one read the same queue the same
    way: each camera's datagrams to its route in the order sent, strangers counted, and one readiness
    event reads at most READ_BATCH, so the loop's other callbacks (timers, the batch's puts) run."""
    from topgimbal import _speedups
    from topgimbal.transport.udp_shared import READ_BATCH, shared_socket

    cameras = [socket.socket(socket.AF_INET, socket.SOCK_DGRAM) for _ in range(3)]
    for c in cameras:
        c.bind(("127.0.0.1", 0))
    got: dict[int, list[bytes]] = {0: [], 1: []}
    shared = shared_socket(socket.AF_INET)
    try:
        shared.loop.remove_reader(shared.sock.fileno())  # read here, by hand, one event at a time
        shared._recv_many = _speedups.recv_many(ext=_speedups.load_extension()) if path == "recvmmsg" else None
        assert (shared._recv_many is None) == (path == "recvfrom_into")
        for i in (0, 1):  # cameras[2] is a stranger
            assert shared.register(cameras[i].getsockname(), got[i].append)
        sent: dict[int, list[bytes]] = {0: [], 1: []}
        for n in range(READ_BATCH + 100):
            i = n % 3
            data = f"#{n:05d}".encode()
            cameras[i].sendto(data, shared.local_address)
            if i < 2:
                sent[i].append(data)
        shared._readable()
        first = len(got[0]) + len(got[1]) + shared.strangers
        assert first == READ_BATCH  # one event: READ_BATCH datagrams (all were queued by then)
        for _ in range(50):
            shared._readable()
            await asyncio.sleep(0.001)
        assert got == sent
        assert shared.strangers == (READ_BATCH + 100) // 3
        assert shared.received == len(sent[0]) + len(sent[1]) and shared.read_errors == 0
    finally:
        shared.close()
        for c in cameras:
            c.close()


def _senders(n: int) -> list[socket.socket]:
    out = [socket.socket(socket.AF_INET, socket.SOCK_DGRAM) for _ in range(n)]
    for s in out:
        s.bind(("127.0.0.1", 0))
    return out


async def _until(cond: object, what: str, timeout_s: float = 10.0) -> None:
    assert callable(cond)
    for _ in range(int(timeout_s / 0.002)):
        if cond():
            return
        await asyncio.sleep(0.002)
    raise AssertionError(f"not within {timeout_s} s: {what}")


@pytest.mark.parametrize("path", ["recvmmsg", "recvfrom_into"])
async def test_a_loaded_socket_is_read_on_a_timer_and_by_readiness_again_once_quiet(path: str) -> None:
    """NAPI's idea: a readiness event that finds POLL_ENTER datagrams waiting turns the socket to
    timed reads (no wake-up per datagram); a timed read that finds fewer than POLL_STAY turns it
    back. Nothing is lost or reordered either way, and one datagram alone never starts the timer."""
    from topgimbal import _speedups
    from topgimbal.transport.udp_shared import POLL_ENTER, shared_socket

    cameras = _senders(2)
    got: dict[int, list[bytes]] = {0: [], 1: []}
    shared = shared_socket(socket.AF_INET)
    try:
        shared._recv_many = _speedups.recv_many(ext=_speedups.load_extension()) if path == "recvmmsg" else None
        for i in (0, 1):
            assert shared.register(cameras[i].getsockname(), got[i].append)
        sent: dict[int, list[bytes]] = {0: [], 1: []}

        def send(first: int, count: int) -> None:
            for n in range(first, first + count):  # no await: all queued before the loop reads
                data = f"#{n:05d}".encode()
                cameras[n % 2].sendto(data, shared.local_address)
                sent[n % 2].append(data)

        send(0, 1)
        await _until(lambda: len(got[0]) == 1, "the first datagram")
        assert shared.polls_started == 0 and not shared.polling  # one datagram: readiness events
        send(1, 4 * POLL_ENTER)
        await _until(lambda: shared.polls_started == 1, "timed reads to start")
        await _until(lambda: got == sent, "every datagram of the burst")
        await _until(lambda: not shared.polling, "readiness events again once traffic stopped")
        send(100, 1)  # the reader is back: a lone datagram is read (and starts no timer)
        await _until(lambda: got == sent, "a datagram after the timed reads ended")
        assert shared.polls_started == 1 and not shared.polling
        assert shared.received == 4 * POLL_ENTER + 2 and shared.read_errors == 0
    finally:
        shared.close()
        for c in cameras:
            c.close()


async def test_a_backlog_is_read_on_at_once_and_closing_stops_the_timed_reads() -> None:
    """A timed read that stops at READ_BATCH leaves a backlog: the next read is the loop's next
    callback, not a timer away. Closing the socket mid-way cancels the next read."""
    from topgimbal.transport.udp_shared import READ_BATCH, shared_socket

    (camera,) = _senders(1)
    got: list[bytes] = []
    shared = shared_socket(socket.AF_INET)
    try:
        assert shared.register(camera.getsockname(), got.append)
        shared.loop.remove_reader(shared.sock.fileno())  # queue a backlog before anything reads
        sent = [f"#{n:05d}".encode() for n in range(3 * READ_BATCH)]
        for data in sent:
            camera.sendto(data, shared.local_address)
        shared._readable()  # READ_BATCH read: the socket turns to timed reads
        assert len(got) == READ_BATCH and shared.polling
        timed = shared._poll_handle
        assert isinstance(timed, asyncio.TimerHandle)
        timed.cancel()
        shared._poll()  # a timed read that finds a full READ_BATCH: the next one at once
        assert len(got) == 2 * READ_BATCH
        assert shared.polling and not isinstance(shared._poll_handle, asyncio.TimerHandle)
        await _until(lambda: got == sent, "the whole backlog")
        camera.sendto(b"#late", shared.local_address)
        shared.close()  # with a read pending or the reader back: nothing runs after this
        assert not shared.polling
        await asyncio.sleep(0.05)
        assert got == sent and shared.read_errors == 0
    finally:
        shared.close()
        camera.close()


async def test_a_timed_read_that_fails_unexpectedly_does_not_stop_the_socket() -> None:
    """A read that raises something unexpected while the socket is on timed reads puts it back on
    readiness events (the loop logs the error): the cameras are read on, not dropped for good."""
    from topgimbal.transport.udp_shared import READ_BATCH, shared_socket

    (camera,) = _senders(1)
    got: list[bytes] = []
    shared = shared_socket(socket.AF_INET)
    try:
        assert shared.register(camera.getsockname(), got.append)
        shared.loop.remove_reader(shared.sock.fileno())
        for n in range(READ_BATCH):
            camera.sendto(f"#{n:05d}".encode(), shared.local_address)
        shared._readable()
        assert shared.polling and len(got) == READ_BATCH
        timed = shared._poll_handle
        assert timed is not None
        timed.cancel()
        real = shared._read

        def broken() -> int:
            raise RuntimeError("a bug in a read")

        shared._read = broken  # type: ignore[method-assign]
        with pytest.raises(RuntimeError, match="a bug in a read"):
            shared._poll()
        shared._read = real  # type: ignore[method-assign]
        assert not shared.polling  # back on readiness events
        camera.sendto(b"#after", shared.local_address)
        await _until(lambda: got[-1:] == [b"#after"], "a datagram after the failed read")
    finally:
        shared.close()
        camera.close()
