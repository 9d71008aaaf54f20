"""`_speedups.recv_many()`: recvmmsg for the fleet server's shared IPv4 UDP socket
(transport/udp_shared.py). What it returns is what a loop of `recvfrom` returns on the same queue:
the same datagrams, whole, in the kernel's order, with the same (host, port); misuse is a clear
error, never a crash. Built from the extension whatever TOPGIMBAL_PURE says (conftest.ext())."""

from __future__ import annotations

import errno
import os
import select
import socket
import time
from collections.abc import Iterator

import pytest

from topgimbal import _speedups

from .conftest import ext

pytestmark = pytest.mark.loopback


@pytest.fixture
def recv_many():  # type: ignore[no-untyped-def]
    fn = _speedups.recv_many(ext=ext())
    assert fn is not None, "built on Linux, the extension has recv_many"
    return fn


@pytest.fixture
def pair() -> Iterator[tuple[socket.socket, list[socket.socket]]]:
    rx = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    rx.bind(("127.0.0.1", 0))
    rx.setblocking(False)
    rx.setsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF, 1 << 20)
    senders = [socket.socket(socket.AF_INET, socket.SOCK_DGRAM) for _ in range(3)]
    for s in senders:
        s.bind(("127.0.0.1", 0))
    yield rx, senders
    for s in (rx, *senders):
        s.close()


def _drain(recv_many, rx: socket.socket, n: int, most: int = 64) -> list[tuple[bytes, object]]:  # type: ignore[no-untyped-def]
    """Every datagram, until `n` have come (loopback delivers at once; bounded wait all the same),
    checking that no call returned more than `most`."""
    got: list[tuple[bytes, object]] = []
    deadline = time.monotonic() + 10
    while len(got) < n and time.monotonic() < deadline:
        select.select([rx], [], [], 0.1)
        chunk = recv_many(rx.fileno(), most)
        assert len(chunk) <= most
        got += chunk
    return got


def test_it_reads_what_recvfrom_reads_in_the_same_order(recv_many, pair) -> None:  # type: ignore[no-untyped-def]
    rx, senders = pair
    sent = []
    for i in range(150):  # more than one call's 64, from three addresses, sizes 0..149
        s = senders[i % 3]
        data = bytes([i % 256]) * i
        s.sendto(data, rx.getsockname())
        sent.append((data, s.getsockname()))
    got = _drain(recv_many, rx, 150)
    assert got == sent  # whole (an empty datagram too), in order, (host, port) as recvfrom gives it
    assert recv_many(rx.fileno(), 64) == []  # nothing waiting: an empty list, not an error


def test_a_datagram_of_the_largest_size_is_not_truncated(recv_many, pair) -> None:  # type: ignore[no-untyped-def]
    rx, (tx, *_) = pair
    big = os.urandom(65507)  # the largest IPv4 UDP payload
    tx.sendto(big, rx.getsockname())
    tx.sendto(b"after", rx.getsockname())
    assert _drain(recv_many, rx, 2) == [(big, tx.getsockname()), (b"after", tx.getsockname())]


def test_max_bounds_each_call(recv_many, pair) -> None:  # type: ignore[no-untyped-def]
    rx, (tx, *_) = pair
    for i in range(5):
        tx.sendto(bytes([i]), rx.getsockname())
    assert [d for d, _ in _drain(recv_many, rx, 5, most=2)] == [bytes([i]) for i in range(5)]


def test_an_ipv6_sender_has_no_ipv4_address(recv_many) -> None:  # type: ignore[no-untyped-def]
    if not socket.has_ipv6:
        pytest.fail("this machine has no IPv6: the test needs ::1")
    rx = socket.socket(socket.AF_INET6, socket.SOCK_DGRAM)
    tx = socket.socket(socket.AF_INET6, socket.SOCK_DGRAM)
    try:
        rx.bind(("::1", 0))
        rx.setblocking(False)
        tx.sendto(b"v6", rx.getsockname()[:2])
        assert _drain(recv_many, rx, 1) == [(b"v6", None)]  # a stranger to every IPv4 route
    finally:
        rx.close()
        tx.close()


@pytest.mark.parametrize(
    ("args", "error", "said"),
    [
        ((0, 0), ValueError, "max 0: expected 1..64 datagrams"),
        ((0, 65), ValueError, "max 65: expected 1..64 datagrams"),
        ((-1, 8), ValueError, "file descriptor -1: expected an open socket's (>= 0)"),
        (("3", 8), TypeError, "integer"),
        ((3,), TypeError, "recv_many"),
    ],
)
def test_misuse_is_a_clear_error(recv_many, args, error, said) -> None:  # type: ignore[no-untyped-def]
    with pytest.raises(error) as info:
        recv_many(*args)
    assert said in str(info.value)


def test_a_closed_or_non_socket_descriptor_is_the_os_error(recv_many, tmp_path) -> None:  # type: ignore[no-untyped-def]
    s = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    fd = s.fileno()
    s.close()
    with pytest.raises(OSError) as closed:
        recv_many(fd, 8)
    assert closed.value.errno == errno.EBADF
    with open(tmp_path / "f", "wb") as f, pytest.raises(OSError) as not_socket:
        recv_many(f.fileno(), 8)
    assert not_socket.value.errno == errno.ENOTSOCK
