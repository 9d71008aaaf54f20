"""Helpers for the simulator tests: frames from the catalog, loopback clients."""

from __future__ import annotations

import asyncio
import socket
from typing import Any

import pytest

from topgimbal.protocol import Frame, FrameParser, get_model, make_frame
from topgimbal.sim import FakeClock
from topgimbal.sim.device import Device

LOOP = "127.0.0.1"


def req(model: str, ident: str, *, read: bool = False, **values: Any) -> bytes:
    """A request of `model`'s dialect, from the catalog, as bytes."""
    dialect, m = get_model(model)
    return dialect.encode(
        ident, read=read, src=m.host_address if m.host_address in dialect.host_addresses else None, **values
    ).to_bytes()


def raw(
    ident: str, data: str = "00", *, src: str = "U", dst: str = "D", rw: str = "w", header: str | None = None
) -> bytes:
    return make_frame(ident, data, src=src, dst=dst, rw=rw, header=header).to_bytes()


def frames(data: bytes) -> list[Frame]:
    return [f for f in FrameParser().feed_datagram(data) if isinstance(f, Frame)]


class DeviceHarness:
    """A sans-I/O device on a fake clock, with one pretend peer."""

    def __init__(self, model: str, **kw: Any) -> None:
        self.clock = FakeClock()
        self.dev = Device(model, clock=self.clock, **kw)
        self.dialect = self.dev.dialect

    def send(self, data: bytes, peer: str = "host") -> list[Frame]:
        out: list[Frame] = []
        for o in self.dev.receive(peer, data):
            out += frames(o.data)
        return out

    def ask(self, ident: str, *, read: bool = False, **values: Any) -> list[Frame]:
        return self.send(req(self.dev.model.name, ident, read=read, **values))

    def decode(self, frame: Frame) -> dict[str, Any]:
        msg = self.dialect.decode(frame)
        assert msg.fields is not None, msg.error
        return msg.fields

    def advance(self, dt: float) -> list[Frame]:
        out: list[Frame] = []
        end = self.clock.now() + dt
        while True:
            nxt = self.dev.next_due()
            if nxt is None or nxt > end:
                break
            self.clock.set(max(nxt, self.clock.now()))
            out += [f for o in self.dev.tick() for f in frames(o.data)]
        self.clock.set(end)
        out += [f for o in self.dev.tick() for f in frames(o.data)]
        return out


@pytest.fixture
def harness() -> type[DeviceHarness]:
    return DeviceHarness


class UdpClient:
    def __init__(self, addr: tuple[str, int]) -> None:
        assert addr[0] == LOOP
        self.addr = addr
        self.sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        self.sock.bind((LOOP, 0))
        self.sock.setblocking(False)

    async def request(self, data: bytes, *, wait: float = 1.0, count: int = 1) -> list[Frame]:
        loop = asyncio.get_running_loop()
        await loop.sock_sendto(self.sock, data, self.addr)
        return await self.collect(wait=wait, count=count)

    async def collect(self, *, wait: float = 1.0, count: int | None = None) -> list[Frame]:
        loop = asyncio.get_running_loop()
        out: list[Frame] = []
        deadline = loop.time() + wait
        while count is None or len(out) < count:
            left = deadline - loop.time()
            if left <= 0:
                break
            try:
                data = await asyncio.wait_for(loop.sock_recv(self.sock, 4096), left)
            except asyncio.TimeoutError:
                break
            out += frames(data)
        return out

    def close(self) -> None:
        self.sock.close()
