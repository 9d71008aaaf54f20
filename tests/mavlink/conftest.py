"""A pymavlink peer on loopback UDP and a rig: simulator + bridge + peer, all on ephemeral ports."""

from __future__ import annotations

import asyncio
import contextlib
import math
import os
import subprocess
import tempfile
from collections.abc import AsyncIterator, Callable
from pathlib import Path
from typing import Any

import pytest
from pymavlink.dialects.v20 import common as ml

from topgimbal.mavlink import Bridge, BridgeConfig
from topgimbal.sim import Simulator
from waiting import until

NAN = float("nan")
# A rig's bridge and simulator close in well under a second; the bound is for a hang, never for
# speed, and in real seconds (virtual.close_all says why virtual ones ran out beside busy loops).
CLOSE_S = 60.0


_KEPT: list[Any] = []  # MAVSDK objects never destroyed nor unsubscribed: see mavsdk_session


def keep(*objects: Any) -> None:
    """Hold MAVSDK objects (plugins, subscriptions) until the caged child ends: freed or closed while
    MAVSDK's threads still called into them, they crashed the process (see mavsdk_session)."""
    _KEPT.extend(objects)


@contextlib.asynccontextmanager
async def mavsdk_session(cfg: Any) -> AsyncIterator[Any]:
    """`Mavsdk(cfg)` for a test in the cage (tests/cage.py: `pytest.mark.cage`), never destroyed.

    MAVSDK 4.1's `destroy` blocked for good inside `mavsdk_camera_destroy` (a C call; seen on 2 of 2
    serial passes of a quiet machine, and before on loaded ones), and destroyed from another thread
    it crashed the process. So it is not called: the instance is kept alive (its plugins destroy
    themselves in `__del__`, the same call) until the caged child leaves with `os._exit` and the
    kernel reclaims it. Outside the cage this refuses to run, so no test can bring the hang back.
    Nor is anything unsubscribed or freed (`keep`): MAVSDK's threads crashed the process (a segfault
    while the test went on, and once in its teardown) after a subscription was closed or a plugin's
    wrapper was collected, seen at load 40."""
    from mavsdk.asyncio import Mavsdk

    from cage import in_child

    if not in_child():
        raise AssertionError("a MAVSDK test runs in the cage: mark it `pytest.mark.cage(BOUND_S)` (tests/cage.py)")
    # MAVSDK caches the camera definitions it downloads under ~/.cache/mavsdk. A cache left by an
    # earlier run let every later one skip the download, the path each ground station's first
    # connection takes, and hid MAVSDK 4.1's deadlock on it (camdef/pacing.py) from all but a
    # fresh machine. Every session here starts cold (the caged child ends with the test).
    os.environ["HOME"] = tempfile.mkdtemp(prefix="mavsdk-home-")
    mavsdk = Mavsdk(cfg)
    _KEPT.append(mavsdk)
    yield mavsdk


class Peer:
    """A ground station (or autopilot) made of pymavlink's codec and a UDP socket."""

    def __init__(self, sysid: int = 255, compid: int = 190) -> None:
        self.mav = ml.MAVLink(None, srcSystem=sysid, srcComponent=compid)
        self.parser = ml.MAVLink(None)
        self.messages: list[Any] = []
        self._waiters: list[tuple[Callable[[Any], bool], asyncio.Future[Any]]] = []
        self.transport: asyncio.DatagramTransport | None = None

    async def connect(self, port: int) -> Peer:
        peer = self

        class P(asyncio.DatagramProtocol):
            def datagram_received(self, data: bytes, addr: Any) -> None:
                for m in peer.parser.parse_buffer(data) or []:
                    peer._got(m)

        loop = asyncio.get_running_loop()
        self.transport, _ = await loop.create_datagram_endpoint(P, remote_addr=("127.0.0.1", port))
        self.send(ml.MAVLink_heartbeat_message(6, 8, 0, 0, 4, 3))
        return self

    def close(self) -> None:
        if self.transport is not None:
            self.transport.close()

    def _got(self, m: Any) -> None:
        self.messages.append(m)
        del self.messages[:-5000]
        for pred, fut in list(self._waiters):
            if not fut.done() and pred(m):
                fut.set_result(m)

    def send(self, msg: Any) -> None:
        assert self.transport is not None
        self.transport.sendto(msg.pack(self.mav))
        self.mav.seq = (self.mav.seq + 1) % 256

    async def wait(self, kind: str, pred: Callable[[Any], bool] = lambda m: True, timeout: float = 5.0) -> Any:
        fut: asyncio.Future[Any] = asyncio.get_running_loop().create_future()
        entry = (lambda m: m.get_type() == kind and pred(m), fut)
        self._waiters.append(entry)
        try:
            return await asyncio.wait_for(fut, timeout)
        finally:
            self._waiters.remove(entry)

    def command(self, compid: int, command: int, *params: float, confirmation: int = 0) -> None:
        p = list(params) + [0.0] * (7 - len(params))
        self.send(ml.MAVLink_command_long_message(1, compid, command, confirmation, *p))

    def command_int(self, compid: int, command: int, *params: float, frame: int = 0) -> None:
        p = list(params) + [0.0] * (7 - len(params))
        self.send(ml.MAVLink_command_int_message(1, compid, frame, command, 0, 0, p[0], p[1], p[2], p[3],
                                                 int(p[4]), int(p[5]), p[6]))  # fmt: skip

    async def ack(self, compid: int, command: int, *params: float, timeout: float = 8.0, **kw: Any) -> Any:
        """Send a command and return its final (not in-progress) COMMAND_ACK from `compid`."""
        fut = asyncio.ensure_future(
            self.wait(
                "COMMAND_ACK",
                lambda m: m.command == command and m.result != 5 and m.get_srcComponent() == compid,
                timeout,
            )
        )
        try:
            await asyncio.sleep(0)
            if kw.pop("as_int", False):
                self.command_int(compid, command, *params, **kw)
            else:
                self.command(compid, command, *params, **kw)
            return await fut
        finally:
            # cancelled before awaiting it (a discovery stopped): an orphaned waiter's TimeoutError,
            # never retrieved, was logged from the garbage collector at a random later moment
            # (once inside ast.parse: CPython 3.11's "AST constructor recursion depth mismatch")
            fut.cancel()

    async def request(self, compid: int, msgid: int, kind: str, param2: float = 0.0, timeout: float = 5.0) -> Any:
        fut = asyncio.ensure_future(self.wait(kind, lambda m: m.get_srcComponent() == compid, timeout))
        try:
            await asyncio.sleep(0)
            ack = await self.ack(compid, 512, msgid, param2)
            assert ack.result == 0, f"REQUEST_MESSAGE {msgid}: result {ack.result}"
            return await fut
        finally:
            fut.cancel()  # as in ack()


class Rig:
    def __init__(self, sim: Simulator, bridge: Bridge, peer: Peer) -> None:
        self.sim, self.bridge, self.peer = sim, bridge, peer


EVENTUALLY_FLOOR_S = 30.0  # every wait here is a bound on a hang, never a speed check


async def eventually(check: Callable[[], bool], timeout: float = 8.0, what: str = "condition") -> None:
    """Wait for `check()`; `timeout` is how long it may take on a quiet machine, and the bound is
    never under EVENTUALLY_FLOOR_S: beside a busy CI, 5-10 s bounds ran out on real-time rigs
    (a gimbal's 60 degree turn is 4.7 s on a C12's motors alone). tests/waiting.py: its failure
    shows the last values."""
    await until(what, check, bound_s=max(timeout, EVENTUALLY_FLOOR_S))


def nan_free(values: Any) -> bool:
    return all(not math.isnan(v) for v in values)


@pytest.fixture
async def rig_factory() -> AsyncIterator[Callable[..., Any]]:
    made: list[Rig] = []

    async def make(model: str = "C12", **config: Any) -> Rig:
        sim = Simulator(model)
        await sim.start(udp=[("127.0.0.1", 0)])
        config.setdefault("endpoints", ["udpin:127.0.0.1:0"])
        # Generous by default: on a loaded machine (six workers on two cores) a healthy camera's
        # answer was once 0.8 s late, the old 0.6 s silence declared the link lost and an unrelated
        # REQUEST_MESSAGE failed (a CI flake). A test about a silent camera passes `silence=True`.
        short = config.pop("silence", False)
        config.setdefault("silence_s", 0.6 if short else 5.0)
        config.setdefault("timeout_s", 0.3 if short else 1.5)
        config.setdefault("retries", 1)
        bridge = Bridge(BridgeConfig(url=sim.url, model=model, **config))
        await bridge.start()
        peer = Peer()
        if config.get("signing_key") is not None:  # an unsigned sender is no peer: it would hear nothing
            from topgimbal.links.signing import sign_outgoing

            sign_outgoing(peer.mav, config["signing_key"])
        await peer.connect(bridge.addresses[0][1])  # type: ignore[index]
        await peer.wait("HEARTBEAT")
        rig = Rig(sim, bridge, peer)
        made.append(rig)
        return rig

    yield make
    for r in made:
        r.peer.close()
        # bounded: a close that never returns fails the test here (and says which) instead of
        # holding an xdist worker until the run's own limit (seen once in a full parallel run)
        for what, closing in (("bridge.close()", r.bridge.close()), ("sim.stop()", r.sim.stop())):
            try:
                await asyncio.wait_for(closing, CLOSE_S)
            except asyncio.TimeoutError:
                raise AssertionError(f"{what} did not return within {CLOSE_S} s") from None


@pytest.fixture
async def rig(rig_factory: Callable[..., Any]) -> Rig:
    r: Rig = await rig_factory("C12")
    return r


@pytest.fixture
async def vrig_maker() -> AsyncIterator[Callable[..., Any]]:
    """Simulator, bridge and peer on memory links (tests/mavlink/virtual.py), on looptime's virtual
    clock: the virtual tier's counterpart of the UDP one above. (No loopback words in here:
    tests/conftest.py reads this source to find the tier of a test that uses it.)"""
    from . import virtual

    async with virtual.vrigs() as make:
        yield make


@pytest.fixture(scope="module")
def source(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A 3 s H.264 clip ffmpeg makes (keyframes every second): what the KLV recorder tests record."""
    path = tmp_path_factory.mktemp("video") / "in.mp4"
    subprocess.run(
        ["ffmpeg", "-loglevel", "error", "-y", "-f", "lavfi", "-i", "testsrc=size=320x240:rate=10", "-t", "3",
         "-c:v", "libx264", "-pix_fmt", "yuv420p", "-g", "10", str(path)],
        check=True, timeout=60,
    )  # fmt: skip
    return path
