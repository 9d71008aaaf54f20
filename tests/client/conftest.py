"""Fixtures for the client tests: a scriptable fake device on loopback or on an in-memory port
(for transport, matching and link edge cases; `memory://` needs no socket) and the real simulator
(for end-to-end tests). Ports are always 0."""

from __future__ import annotations

import asyncio
import itertools
from collections.abc import AsyncIterator, Callable

import pytest

from topgimbal.errors import TopGimbalError
from topgimbal.protocol import Frame, FrameParser, get_model
from topgimbal.transport.memory import MemoryPort
from virtual_time import Made

Handler = Callable[[Frame], "list[bytes] | None"]
_names = itertools.count(1)


class FakeDevice:
    """Answers each frame with `handler(frame)` (a list of raw byte strings to send back, each
    one datagram / write). Default: the protocol's rule, echo writes, answer reads from `answers`."""

    def __init__(self, model: str = "C12") -> None:
        self.dialect, self.model = get_model(model)
        self.received: list[Frame] = []
        self.answers: dict[str, dict] = {"VER": {"version": "1.5.2"}}
        self.handler: Handler = self.default
        self.udp: asyncio.DatagramTransport | None = None
        self.tcp: asyncio.base_events.Server | None = None
        self.tcp_peers: list[asyncio.Transport] = []
        self.port: MemoryPort | None = None
        self.url = ""
        self.muted = False  # a device that has gone quiet: it hears, does, and says nothing
        self.attitude = (0.0, 0.0, 0.0)  # what GAC answers and streams carry (wire values)
        self._stream: asyncio.Task[None] | None = None

    def default(self, frame: Frame) -> list[bytes] | None:
        if frame.ident == "GAA" and frame.rw == "w":
            self._set_stream(int(frame.data, 16))
        if frame.ident == "GAC" and frame.rw == "r" and "GAC" not in self.answers:
            y, p, r = self.attitude
            return [self.dialect.response(frame, yaw_deg=y, pitch_deg=p, roll_deg=r).to_bytes()]
        if frame.rw == "w":
            return [frame.swapped().to_bytes()]
        values = self.answers.get(frame.ident)
        if values is None:
            return None
        try:
            return [self.dialect.response(frame, **values).to_bytes()]
        except TopGimbalError:  # an answer meant for the other dialect (VER): stay silent, as a device would
            return None

    def _handle(self, data: bytes, parser: FrameParser, send: Callable[[bytes], None]) -> None:
        for item in parser.feed(data):
            if isinstance(item, Frame):
                self.received.append(item)
                for out in self.handler(item) or []:
                    if not self.muted:
                        send(out)

    def _set_stream(self, rate_hz: int) -> None:
        """SkyDroid GAA: GAC frames at `rate_hz` (0: off), to the memory client."""
        if self._stream is not None:
            self._stream.cancel()
            self._stream = None
        if rate_hz and self.port is not None:
            self._stream = asyncio.ensure_future(self._run_stream(1.0 / rate_hz))

    async def _run_stream(self, period: float) -> None:
        while True:
            await asyncio.sleep(period)
            if self.port is not None and not self.muted:
                y, p, r = self.attitude
                frame = self.dialect.notification("GAC", src="G", rw="r", yaw_deg=y, pitch_deg=p, roll_deg=r)
                self.port.send(frame.to_bytes())

    def start_memory(self) -> str:
        """Listen on a fresh `memory://` port (datagram semantics)."""
        self.port = port = MemoryPort.listen(f"fake-{next(_names)}")
        port.on_bytes = lambda data: self._handle(data, FrameParser(), port.send)
        self.url = port.url
        return self.url

    async def start_udp(self) -> str:
        loop = asyncio.get_running_loop()
        dev = self

        class P(asyncio.DatagramProtocol):
            def connection_made(self, t: asyncio.BaseTransport) -> None:
                self.t = t

            def datagram_received(self, data: bytes, addr: tuple) -> None:
                dev._handle(data, FrameParser(), lambda b: self.t.sendto(b, addr))  # type: ignore[attr-defined]

        self.udp, _ = await loop.create_datagram_endpoint(P, local_addr=("127.0.0.1", 0))
        port = self.udp.get_extra_info("sockname")[1]
        self.url = f"udp://127.0.0.1:{port}"
        return self.url

    async def start_tcp(self) -> str:
        dev = self

        class P(asyncio.Protocol):
            def connection_made(self, t: asyncio.BaseTransport) -> None:
                self.t = t
                self.parser = FrameParser()
                dev.tcp_peers.append(t)  # type: ignore[arg-type]

            def data_received(self, data: bytes) -> None:
                dev._handle(data, self.parser, self.t.write)  # type: ignore[attr-defined]

        self.tcp = await asyncio.get_running_loop().create_server(P, "127.0.0.1", 0)
        port = self.tcp.sockets[0].getsockname()[1]
        self.url = f"tcp://127.0.0.1:{port}"
        return self.url

    async def stop(self) -> None:
        if self._stream is not None:
            self._stream.cancel()
        if self.port is not None:
            self.port.close()
        if self.udp is not None:
            self.udp.close()
        for t in self.tcp_peers:
            t.close()
        if self.tcp is not None:
            self.tcp.close()
            await self.tcp.wait_closed()


@pytest.fixture
async def fake() -> AsyncIterator[FakeDevice]:
    dev = FakeDevice()
    yield dev
    await dev.stop()


@pytest.fixture
async def sim_factory():
    """Start simulators listening on loopback UDP and TCP (port 0) and a pty serial line."""
    from topgimbal.sim import Simulator

    started = []

    async def make(model: str = "C12", **kw):
        sim = Simulator(model=model, **kw)
        await sim.start(udp=[("127.0.0.1", 0)], tcp=[("127.0.0.1", 0)], serial=["pty"])
        started.append(sim)
        return sim

    yield make
    for sim in started:
        await sim.stop()


@pytest.fixture
async def memory_sim():
    """Start simulators that serve only `memory://` (no socket): with `pytest.mark.looptime` their
    faults, delays and the client's timeouts run in virtual time. `make(model, **kw)` -> (sim, url)."""
    from topgimbal.sim import Simulator

    started = []
    clock = Made()  # tests/virtual_time.py: stopped on the clock they were made on

    async def make(model: str = "C12", **kw):
        clock.note()
        sim = await Simulator(model=model, **kw).start(udp=[])
        started.append(sim)
        return sim, sim.listen_memory(f"sim-{next(_names)}")

    yield make
    with clock.clock():
        for sim in started:
            await sim.stop()


class KinematicFake:
    """A gimbal with physics on a `memory://` port for pointing tests (no sockets): rate commands
    accelerate each axis (at most `accel`), angle commands slew to their target unless the model's
    profile lists them as `ignored` (the C11) or `ignore_angles` says the firmware ignores them
    silently; echoes writes (except the profile's `no_echo`); streams GAC at the model's fixed rate
    or as asked; answers GAC queries. Values pass through the model's wire signs. Every position
    is kept in `history` (to measure overshoot)."""

    def __init__(self, model: str, *, ignore_angles: bool = False, accel: float = 300.0, tick_s: float = 0.005) -> None:
        from topgimbal.protocol.signs import flip, resolve_signs

        self.dialect, self.model = get_model(model)
        self._flip, self.signs = flip, resolve_signs(self.model)
        self.ignored = set(self.model.ignored) | ({"GAM", "GAY", "GAP"} if ignore_angles else set())
        self.accel, self.tick_s = accel, tick_s
        self.pos = {"yaw": 0.0, "pitch": 0.0}
        self.vel = {"yaw": 0.0, "pitch": 0.0}
        self.rate = {"yaw": 0.0, "pitch": 0.0}  # commanded rate
        self.goal: dict[str, tuple[float, float]] = {}  # axis -> (angle, speed) of an angle command
        self.received: list[Frame] = []
        self.history: list[tuple[float, float, float]] = []
        self.stream_hz = 0.0
        self.port = MemoryPort.listen(f"kin-{next(_names)}")
        self.port.on_bytes = self._on_bytes
        self.url = self.port.url
        self._tasks: list[asyncio.Task[None]] = []

    def start(self) -> KinematicFake:
        self._tasks.append(asyncio.ensure_future(self._physics()))
        self._tasks.append(asyncio.ensure_future(self._stream()))
        return self

    def _on_bytes(self, data: bytes) -> None:
        for frame in FrameParser().feed(data):
            if isinstance(frame, Frame):
                self.received.append(frame)
                self._handle(frame)

    def _handle(self, frame: Frame) -> None:
        spec = self.dialect.commands.get(frame.ident)
        msg = self.dialect.decode(frame)
        if spec is None or msg.fields is None:
            return
        api = self._flip(spec, msg.fields, self.signs)
        if frame.rw == "r":
            if spec.role == "attitude":
                y, p = self._wire_attitude()
                self.port.send(self.dialect.response(frame, yaw_deg=y, pitch_deg=p, roll_deg=0.0).to_bytes())
            return
        if spec.role == "attitude_stream":
            rate = float(api.get("rate_hz", 10 if api.get("state") == "on" else 0))
            self.stream_hz = self.model.stream_rates_hz.get(frame.ident, rate) if rate else 0.0
        elif frame.ident not in self.ignored and spec.role == "rate":
            for f in spec.forms_for("w", "request")[0].fields:
                if f.axis in self.rate:
                    self.rate[f.axis] = float(api[f.name])
                    self.goal.pop(f.axis, None)
        elif frame.ident not in self.ignored and spec.role == "angle":
            speed = next((float(v) for k, v in api.items() if k.endswith("speed_deg_s")), 9.9) or 9.9
            for f in spec.forms_for("w", "request")[0].fields:
                if f.axis in self.pos:
                    self.goal[f.axis] = (float(api[f.name]), speed)
        elif spec.role == "gimbal_control" and api.get("action") == "stop":
            self.rate = {"yaw": 0.0, "pitch": 0.0}
            self.goal.clear()
        if frame.ident not in self.model.no_echo:
            self.port.send(frame.swapped().to_bytes())

    def _wire_attitude(self) -> tuple[float, float]:
        spec = self.dialect.command("GAC")
        wire = self._flip(
            spec, {"yaw_deg": self.pos["yaw"], "pitch_deg": self.pos["pitch"], "roll_deg": 0.0}, self.signs
        )
        return round(wire["yaw_deg"], 2), round(wire["pitch_deg"], 2)

    async def _physics(self) -> None:
        loop = asyncio.get_running_loop()
        last = loop.time()
        while True:
            await asyncio.sleep(self.tick_s)
            now = loop.time()
            dt, last = now - last, now
            for axis in self.pos:
                if axis in self.goal:
                    target, speed = self.goal[axis]
                    err = target - self.pos[axis]
                    want = max(-speed, min(speed, err / max(dt, 1e-3)))
                else:
                    want = self.rate[axis]
                dv = max(-self.accel * dt, min(self.accel * dt, want - self.vel[axis]))
                self.vel[axis] += dv
                self.pos[axis] += self.vel[axis] * dt
            self.history.append((now, self.pos["yaw"], self.pos["pitch"]))

    async def _stream(self) -> None:
        while True:
            await asyncio.sleep(1.0 / self.stream_hz if self.stream_hz else 0.02)
            if self.stream_hz:
                y, p = self._wire_attitude()
                self.port.send(
                    self.dialect.notification("GAC", src="G", rw="r", yaw_deg=y, pitch_deg=p, roll_deg=0.0).to_bytes()
                )

    async def stop(self) -> None:
        for t in self._tasks:
            t.cancel()
        self.port.close()


@pytest.fixture
async def kinematic():
    made: list[KinematicFake] = []
    clock = Made()  # tests/virtual_time.py: stopped on the clock they were made on

    def make(model: str, **kw) -> KinematicFake:
        clock.note()
        dev = KinematicFake(model, **kw).start()
        made.append(dev)
        return dev

    yield make
    with clock.clock():
        for dev in made:
            await dev.stop()
