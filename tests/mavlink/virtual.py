"""The virtual rig: the simulator on `memory://`, the bridge on a `memory:` MAVLink link and a
pymavlink peer on that link, with no socket anywhere. Under `pytest.mark.looptime` (which
tests/conftest.py adds to every virtual-tier coroutine) every timer in the camera, the client,
the bridge and the peer runs in virtual time: a 30 s give-up takes no real time, and a test can
assert the exact timeouts and retry counts the product has, not scaled-down ones.

    async def test_x(vrig_maker):                 # tests/mavlink/conftest.py provides the fixture
        vrig = await vrig_maker("C12", silence_s=0.6)
        ack = await vrig.peer.ack(154, ...)

Fixtures and helpers here are named so that tests/conftest.py's tier detection (its LOOPBACK
words: no addresses, no `Bridge(`, no `rig` alone) counts a module that uses them as virtual. A
module that mixes them with the UDP rig marks its virtual tests itself (`in_virtual_time` below)."""

from __future__ import annotations

import asyncio
import contextlib
import io
import itertools
import os
import random
import time
from collections.abc import AsyncIterator, Callable
from typing import Any, TypeVar

import pytest
from pymavlink.dialects.v20 import common as ml

from topgimbal.clock import monotonic
from topgimbal.links.memory_link import MemoryPeer, connect_memory
from topgimbal.mavlink import bridge as bridge_mod
from topgimbal.sim import FaultPlan, Simulator
from topgimbal.sim.faults import FaultInjector
from virtual_time import Made

from .conftest import CLOSE_S, Peer

# For the virtual tests of a module that also holds loopback ones (its source names the UDP rig):
# `@in_virtual_time` on a test, or `marks=VIRTUAL` on a parameter.
VIRTUAL = [pytest.mark.virtual, pytest.mark.looptime]
F = TypeVar("F", bound=Callable[..., Any])


def in_virtual_time(test: F) -> F:
    """Marks a test virtual (tier) and looptime (its timers on the virtual clock)."""
    marked: F = pytest.mark.looptime(pytest.mark.virtual(test))
    return marked


_names = itertools.count()


def fresh_name(kind: str) -> str:
    """A name no other test in this process uses (the memory tables are process-wide)."""
    return f"v{kind}-{os.getpid()}-{next(_names)}"


class MemPeer(Peer):
    """The conftest's pymavlink peer, on a `memory:` link instead of a UDP socket."""

    end: MemoryPeer | None = None

    async def join(self, name: str, heartbeat: bool = True) -> MemPeer:
        self.end = connect_memory(name, self._bytes)
        if heartbeat:
            self.send(ml.MAVLink_heartbeat_message(6, 8, 0, 0, 4, 3))
        return self

    def _bytes(self, data: bytes) -> None:
        for m in self.parser.parse_buffer(data) or []:
            self._got(m)

    def send(self, msg: Any) -> None:
        assert self.end is not None
        self.end.send(msg.pack(self.mav))
        self.mav.seq = (self.mav.seq + 1) % 256

    def close(self) -> None:
        if self.end is not None:
            self.end.close()


class VRig:
    """A simulator, its bridge and one peer; `link` is the bridge's MAVLink link name (another
    peer joins with `await MemPeer(...).join(vrig.link)`), `camera_name` the simulator's."""

    def __init__(self, sim: Simulator, bridge: Any, peer: MemPeer, link: str, camera_name: str) -> None:
        self.sim, self.bridge, self.peer, self.link, self.camera_name = sim, bridge, peer, link, camera_name
        self.extra: list[Any] = []  # more simulators / bridges / peers the test started (closed at the end)


async def start_camera(model: str = "C12", name: str | None = None, **sim_kw: Any) -> tuple[Simulator, str]:
    """A simulator serving only `memory://NAME`; (simulator, its URL)."""
    sim = await Simulator(model, **sim_kw).start(udp=[])
    return sim, sim.listen_memory(name or fresh_name("cam"))


async def start_bridge(url: str, model: str, link: str, camera_wait_s: float = 2.0, **config: Any) -> Any:
    """A bridge for the camera at `url` on `memory:LINK`; the camera definitions only over MAVLink
    FTP (their HTTP server would bind a socket). Config defaults are the product's own."""
    config.setdefault("endpoints", [f"memory:{link}"])
    config.setdefault("definition_http", None)
    made = bridge_mod.Bridge(bridge_mod.BridgeConfig(url=url, model=model, **config))
    return await made.start(camera_wait_s=camera_wait_s)


async def start_vrig(model: str = "C12", *, sim_kw: dict[str, Any] | None = None, camera_wait_s: float = 2.0,
                     **config: Any) -> VRig:  # fmt: skip
    sim, url = await start_camera(model, **(sim_kw or {}))
    link = fresh_name("gcs")
    try:
        made = await start_bridge(url, model, link, camera_wait_s, **config)
    except BaseException:
        await sim.stop()
        raise
    peer = MemPeer()
    if config.get("signing_key") is not None:  # an unsigned sender is no peer: it would hear nothing
        from topgimbal.links.signing import sign_outgoing

        sign_outgoing(peer.mav, config["signing_key"])
    await peer.join(link)
    await peer.wait("HEARTBEAT")
    return VRig(sim, made, peer, link, url.removeprefix("memory://"))


async def close_all(things: list[Any]) -> None:
    """Peers, bridges and simulators, bounded in real seconds (a close that hangs fails the test,
    naming it). Not in virtual seconds: on looptime's loop, while a close waits, virtual time jumps
    to the next timer at each idle turn, so beside busy loops a close that took a few real seconds
    had used up 60 virtual ones (a fresh-clone run beside two busy loops: ran out at 60 s, the
    camera link's own clock then read 27,141 s)."""
    for thing in things:
        if isinstance(thing, Peer):
            thing.close()
            continue
        closing = asyncio.ensure_future(thing.stop() if isinstance(thing, Simulator) else thing.close())
        deadline = time.monotonic() + CLOSE_S  # real time: the hang bound
        while not closing.done():
            if time.monotonic() > deadline:
                where = io.StringIO()
                closing.print_stack(file=where)  # the await chain it is stuck in
                closing.cancel()
                raise AssertionError(
                    f"{thing!r} did not close within {CLOSE_S} real seconds; it waited at:\n{where.getvalue()}"
                )
            await asyncio.wait({closing}, timeout=1.0)
        closing.result()


@contextlib.asynccontextmanager
async def vrigs() -> AsyncIterator[Callable[..., Any]]:
    """`make(model, **bridge_config)` -> VRig; all closed at the end (conftest's `vrig_maker`)."""
    made: list[VRig] = []
    clock = Made()  # tests/virtual_time.py: closed on the clock they were made on

    async def make(model: str = "C12", **config: Any) -> VRig:
        clock.note()
        v = await start_vrig(model, **config)
        made.append(v)
        return v

    try:
        yield make
    finally:
        with clock.clock():
            for v in made:
                await close_all([v.peer, *v.extra, v.bridge, v.sim])


class HealthLog:
    """The bridge's camera health changes, with the (virtual) time of each: (t, answering)."""

    def __init__(self, made: Any) -> None:
        self.changes: list[tuple[float, bool]] = []
        made.cam.on_health(lambda up: self.changes.append((monotonic(), up)))

    def when(self, up: bool, after: float = float("-inf")) -> float | None:
        return next((t for t, u in self.changes if u == up and t >= after), None)


def camera_input(sim: Simulator) -> list[tuple[float, bytes]]:
    """From now on, every chunk the simulator's memory port gets from its client, timed."""
    port = sim._memory[-1]  # the port listen_memory opened
    got: list[tuple[float, bytes]] = []
    inner = port.on_bytes
    assert inner is not None

    def tap(data: bytes) -> None:
        got.append((monotonic(), data))
        inner(data)

    port.on_bytes = tap
    return got


def silence_replies(sim: Simulator, seconds: float) -> None:
    """From now on, for `seconds`, nothing comes out of the simulated camera; what it is sent it
    still carries out (the simulator's own fault injector, outbound direction only)."""
    now = sim.clock.now()
    sim._fault_out = FaultInjector(FaultPlan(silence=((0.0, seconds),), direction="out"), "out",
                                   random.Random(0), now)  # fmt: skip
