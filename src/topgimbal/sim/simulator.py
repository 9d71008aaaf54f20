"""The simulator: the device core, its servers, the fault plan, persistence and timing.

    sim = Simulator("C12", seed=0)
    await sim.start(udp=[("127.0.0.1", 0)])      # or no arguments: the model's documented ports
    print(sim.url)                                  # udp://127.0.0.1:40123
    ...
    await sim.stop()

`async with Simulator("C12", listen={"udp": [("127.0.0.1", 0)]}) as sim:` starts it with the
`listen` arguments (none: the documented endpoints) and stops it at the end.

With `clock=FakeClock()` nothing happens by itself: `sim.advance(dt)` moves time and sends what
falls due (attitude streams, delayed packets), deterministically.
"""

from __future__ import annotations

import asyncio
import random
from collections.abc import Hashable, Iterable, Mapping, Sequence
from pathlib import Path
from typing import Any, cast

from ..protocol import Dialect, Frame
from ..transport.memory import MemoryPort
from . import persist, precise_timer
from .clock import Clock, FakeClock, MonotonicClock
from .device import TOPOTEK_STREAM_HZ, Device, Outgoing
from .faults import FaultInjector, FaultPlan
from .listen import Address, MemoryPeer, addresses, url_host
from .physics import GimbalPhysics
from .servers import LOOPBACK, Limits, SerialPeer, TcpServer, UdpServer
from .shared_timer import Entry, SharedTimer
from .state import CameraState, NetworkState
from .targets import Target
from .terrain import TerrainGround

# How far ahead of its due time a real-time stream frame may leave (see Device.tick), on the
# loop's millisecond timers; with a timerfd (precise_timer.py) PRECISE_EARLY_S instead.
TIMER_EARLY_S = 0.001


class Simulator:
    def __init__(
        self,
        model: str = "C12",
        *,
        seed: int = 0,
        faults: FaultPlan | None = None,
        state_file: str | Path | None = None,
        quirks: Mapping[str, bool] | None = None,
        clock: Clock | None = None,
        listen: Mapping[str, Any] | None = None,
        topotek_stream_hz: float = TOPOTEK_STREAM_HZ,
        limits: Limits | None = None,
        targets: Sequence[Target] = (),
        terrain: str | Path | TerrainGround | None = None,
        timer: SharedTimer | None = None,
    ) -> None:
        """`timer`: a SharedTimer for the simulators of one process to wake up on (`sim --fleet`:
        one loop timer for all of them); none: this simulator's own asyncio timer."""
        self.clock: Clock = clock if clock is not None else MonotonicClock()
        self.device = Device(
            model, seed=seed, clock=self.clock, quirk_overrides=quirks, topotek_stream_hz=topotek_stream_hz
        )
        self.device.state.targets = tuple(targets)
        self.seed = seed
        if terrain is not None:  # the laser's ground (sim --terrain); a bad file raises DemError here
            self.device.state.terrain = terrain if isinstance(terrain, TerrainGround) else TerrainGround.load(terrain)
        self.faults = faults or FaultPlan()
        self.state_file = Path(state_file) if state_file is not None else None
        self.listen = dict(listen or {})
        self.limits = limits or Limits()
        self.endpoints: list[tuple[str, str]] = []
        self.addresses: dict[str, list[Address]] = {"udp": [], "tcp": []}
        self._udp: list[UdpServer] = []
        self._tcp: list[TcpServer] = []
        self._serial: list[SerialPeer] = []
        self._memory: list[MemoryPort] = []
        self._loop: asyncio.AbstractEventLoop | None = None
        self._shared_timer = timer
        self._timer: asyncio.TimerHandle | Entry | precise_timer.PreciseTimer | None = None
        self._timer_at: float | None = None
        self._precise: precise_timer.PreciseTimer | None = None  # a timerfd, where it can be (start)
        self._early_s = TIMER_EARLY_S
        self._fault_in: FaultInjector | None = None
        self._fault_out: FaultInjector | None = None
        self.started = False
        self._commit: persist.GroupCommit[Outgoing] | None = None
        self._held: dict[Hashable, int] = {}  # peers with replies waiting for the state file
        if self.state_file is not None:
            persist.remove_stale_temps(self.state_file)
            saved = persist.load(self.state_file, template=self.device.snapshot())
            if saved is not None:
                self.device.restore(saved)
            self._commit = persist.GroupCommit(self.state_file, self.device.snapshot, self._commit_done, self._released)

    # -- state the tests read ----------------------------------------------------------------------

    @property
    def model(self) -> str:
        return self.device.model.name

    @property
    def dialect(self) -> Dialect:
        return self.device.dialect

    @property
    def gimbal(self) -> GimbalPhysics:
        return self.device.gimbal

    @property
    def camera(self) -> CameraState:
        return self.device.camera

    @property
    def network(self) -> NetworkState:
        return self.device.network

    @property
    def settings(self) -> dict[str, dict[str, Any]]:
        return self.device.settings

    @property
    def thermal(self) -> dict[str, Any]:
        """The thermal settings this model has, by identifier (IMG palette, TSM scene, ...)."""
        return {
            k: v
            for k, v in self.device.settings.items()
            if k in ("IMG", "TSM", "TAS", "TDI", "TIB", "TIC", "TAR", "TTR", "TGM", "TMR")
        }

    @property
    def quirks(self) -> dict[str, bool]:
        return self.device.quirks

    @property
    def received(self) -> list[Frame]:
        return self.device.received

    @property
    def url(self) -> str:
        if not self.endpoints:
            raise RuntimeError("the simulator is not listening yet: await sim.start() first")
        return self.endpoints[0][1]

    @property
    def fault_counts(self) -> dict[str, dict[str, int]]:
        return {d: dict(i.counts) for d, i in (("in", self._fault_in), ("out", self._fault_out)) if i is not None}

    # -- life cycle --------------------------------------------------------------------------------

    async def start(
        self,
        udp: Iterable[Any] | None = None,
        tcp: Iterable[Any] | None = None,
        serial: Iterable[str] | str | None = None,
    ) -> Simulator:
        """Listen. With no arguments at all: the model's documented endpoints on 127.0.0.1 (a pty
        for a documented serial line). A taken address raises ListenError naming it (a camera's
        port is never moved: clients are configured with it)."""
        if self.started:
            raise RuntimeError("the simulator is already started")
        self._loop = asyncio.get_running_loop()
        if isinstance(self.clock, MonotonicClock):
            self.clock.bind(self._loop)
        if self._shared_timer is None and not isinstance(self.clock, FakeClock):
            # Stream frames at their time, not within the millisecond before it (precise_timer.py).
            self._precise = precise_timer.make(self._loop, self._on_timer)
        self._early_s = TIMER_EARLY_S if self._precise is None else precise_timer.PRECISE_EARLY_S
        if udp is None and tcp is None and serial is None:
            documented = self.documented_listen()
            udp, tcp, serial = documented["udp"], documented["tcp"], documented["serial"]
        if isinstance(serial, str):
            serial = [serial]
        now = self.clock.now()
        self._fault_in = FaultInjector(self.faults, "in", random.Random(f"{self.seed}/in"), now)
        self._fault_out = FaultInjector(self.faults, "out", random.Random(f"{self.seed}/out"), now)
        try:
            for host, port in addresses(udp):
                proto = UdpServer(self._input, self._forget, self.limits, clock=self.clock.now)
                await proto.start(host, port)
                self._udp.append(proto)
                h, p = proto.address
                self.addresses["udp"].append((h, p))
                self.endpoints.append(("udp", f"udp://{url_host(h)}:{p}"))
            for host, port in addresses(tcp):
                server = TcpServer(self._input, self._forget, self.limits)
                await server.start(host, port)
                self._tcp.append(server)
                h, p = server.address
                self.addresses["tcp"].append((h, p))
                self.endpoints.append(("tcp", f"tcp://{url_host(h)}:{p}"))
            for dev in serial or ():
                line = SerialPeer(self._input, dev)
                line.start()
                self._serial.append(line)
                self.endpoints.append(("serial", line.url))
        except BaseException:
            await self.stop()
            raise
        self.started = True
        return self

    def listen_memory(self, name: str) -> str:
        """Serve `memory://NAME` too (after `start()`; one client, one datagram per send): a camera
        with no socket, for tests on a virtual-time loop and for embedding. Returns its URL."""
        if not self.started:
            raise RuntimeError("the simulator is not started: await sim.start() first (udp=[] for no sockets)")
        port = MemoryPort.listen(name)
        peer = MemoryPeer(port)
        port.on_bytes = lambda data: self._input(peer, data, True)
        self._memory.append(port)
        self.endpoints.append(("memory", port.url))
        return port.url

    def documented_listen(self) -> dict[str, list[Any]]:
        """The model's documented endpoints, on loopback (a pty stands in for a UART)."""
        eps = self.device.model.endpoints
        return {
            "udp": [(LOOPBACK, e.port) for e in eps if e.kind == "udp"],
            "tcp": [(LOOPBACK, e.port) for e in eps if e.kind == "tcp"],
            "serial": ["pty" for e in eps if e.kind == "serial"],
        }

    async def stop(self) -> None:
        if self._timer is not None:
            self._timer.cancel()
            self._timer = None
        self._timer_at = None
        if self._precise is not None:
            self._precise.close()
            self._precise = None
        for u in self._udp:
            u.close()
        for t in self._tcp:
            await t.close()
        for s in self._serial:
            s.close()
        self._udp, self._tcp, self._serial = [], [], []
        for m in self._memory:
            m.close()
        self._memory = []
        if self._commit is not None:
            await self._commit.drain()
            self._commit.close()
        self.flush(force=True)
        self.started = False
        if isinstance(self.clock, MonotonicClock):
            self.clock.bind(None)

    async def __aenter__(self) -> Simulator:
        if not self.started:
            await self.start(**self.listen)
        return self

    async def __aexit__(self, *exc: object) -> None:
        await self.stop()

    def flush(self, force: bool = False) -> None:
        """Write the persistent state now if it changed (always with `force`), synchronously."""
        if self.state_file is not None and (self.device.dirty or force):
            persist.save(self.state_file, self.device.snapshot())
            self.device.dirty = False

    def sync(self) -> None:
        """Bring the physics up to now. `gimbal` holds the attitude of the last step the device
        took (a stream's tick, a command), which while it turns is up to a stream period old: a
        test scoring where the camera points at a given instant calls this first (on the
        simulator's loop thread), as `sim --truth` does."""
        self.device.sync()

    @property
    def peers(self) -> dict[str, int]:
        """How many remote ends each kind of server holds now (UDP peers, TCP clients)."""
        return {"udp": sum(len(u.peers) for u in self._udp), "tcp": sum(len(t.peers) for t in self._tcp)}

    @property
    def server_counts(self) -> dict[str, int]:
        """What the limits did so far: peers forgotten and why, clients refused or dropped."""
        out = {"udp_sent": 0, "udp_send_dropped": 0, "tcp_refused": 0, "tcp_overflow_dropped": 0}
        for u in self._udp:
            out["udp_sent"] += u.sent
            out["udp_send_dropped"] += u.dropped
            for why, n in u.forgotten.items():
                out[f"udp_forgotten_{why}"] = out.get(f"udp_forgotten_{why}", 0) + n
        for t in self._tcp:
            out["tcp_refused"] += t.refused
            out["tcp_overflow_dropped"] += t.overflows
        if self._commit is not None:
            out["state_commits"] = self._commit.commits
            out["state_write_failures"] = self._commit.failures
        return out

    # -- traffic -----------------------------------------------------------------------------------

    def _input(self, peer: Hashable, data: bytes, datagram: bool) -> None:
        fi = self._fault_in
        assert fi is not None
        if not fi.enabled:
            self._deliver((peer, datagram), data)
        else:
            for p, d in fi.submit((peer, datagram), data, self.clock.now()):
                self._deliver(p, d)
        self._schedule()

    def _forget(self, peer: Hashable) -> None:
        """A peer went away (TCP closed; UDP unreachable, unheard for a lease or evicted at the
        cap): its streams, parser state and queued packets go with it."""
        self.device.forget(peer)
        if self._fault_out is not None:
            self._fault_out.forget(peer)
        if self._fault_in is not None:
            self._fault_in.forget((peer, False))
            self._fault_in.forget((peer, True))

    def _deliver(self, key: Hashable, data: bytes) -> None:
        peer, datagram = cast("tuple[Hashable, bool]", key)
        outs = self.device.receive(peer, data, datagram=datagram)
        dirty = self.device.dirty
        if self._commit is None or not (dirty or peer in self._held):
            self._send(outs)
            return
        # Write-ahead: a state-changing request is answered once its state is on disk; later
        # replies to the same peer wait with it, so they cannot overtake it.
        self.device.dirty = False
        for o in outs:
            self._held[o.peer] = self._held.get(o.peer, 0) + 1
        self._held.setdefault(peer, 0)
        self._commit.submit(outs, dirty=dirty)
        if not self._held[peer]:
            del self._held[peer]

    def _released(self, outs: list[Outgoing]) -> None:
        """The state file holds what these replies acknowledge (or the write failed: dropped)."""
        for o in outs:
            n = self._held.get(o.peer, 0) - 1
            if n > 0:
                self._held[o.peer] = n
            else:
                self._held.pop(o.peer, None)

    def _commit_done(self, outs: list[Outgoing]) -> None:
        self._released(outs)
        self._send(outs)

    def _send(self, outs: list[Outgoing]) -> None:
        fo = self._fault_out
        now = self.clock.now()
        for o in outs:
            if fo is None or not fo.enabled:
                o.peer.send(o.data)  # type: ignore[attr-defined]
                continue
            for peer, data in fo.submit(o.peer, o.data, now, reply=o.reply):
                peer.send(data)  # type: ignore[attr-defined]

    def pump(self) -> None:
        """Send everything due by now: delayed inbound packets, streams, delayed outbound packets."""
        real_time = not isinstance(self.clock, FakeClock)
        # The timer wakes `_early_s` early: what falls due within that margin goes now, delayed
        # packets as the device's streams do (on a virtual-time loop, where the clock stands still
        # until nothing is ready, waking again for the last millisecond would never end).
        early_s = self._early_s if real_time else 0.0
        now = self.clock.now() + early_s
        fi, fo = self._fault_in, self._fault_out
        if fi is not None and fi.enabled:  # a disabled injector holds nothing (faults.py)
            for p, d in fi.due(now):
                self._deliver(p, d)
        self._send(self.device.tick(early_s=early_s))
        if fo is not None and fo.enabled:
            for peer, data in fo.due(now):
                peer.send(data)  # type: ignore[attr-defined]
        if self.device.dirty and self._commit is not None:
            self.device.dirty = False
            self._commit.submit([], dirty=True)

    def advance(self, dt: float) -> None:
        """Fake clock only: move time by `dt` seconds, sending what falls due on the way, in order."""
        if not isinstance(self.clock, FakeClock):
            raise RuntimeError("advance() needs a simulator built with clock=FakeClock()")
        end = self.clock.now() + dt
        while True:
            nxt = self._next_due()
            if nxt is None or nxt > end:
                break
            self.clock.set(max(self.clock.now(), nxt))
            self.pump()
        self.clock.set(end)
        self.pump()

    def _next_due(self) -> float | None:
        due = self.device.next_due()
        fi, fo = self._fault_in, self._fault_out
        if fi is None and fo is None:  # no fault plan: the common case, once a stream frame
            return due
        for inj in (fi, fo):
            if inj is not None and inj.enabled:  # a disabled injector holds nothing (faults.py)
                t = inj.next_due()
                if t is not None and (due is None or t < due):
                    due = t
        return due

    def _schedule(self) -> None:
        """Real time: one timer for the earliest thing due (re-armed only when that changes)."""
        if self._loop is None or isinstance(self.clock, FakeClock) or not self.started:
            return
        due = self._next_due()
        if due is None:
            return
        if self._timer is not None and self._timer_at is not None and self._timer_at <= due:
            return
        if self._timer is not None:
            self._timer.cancel()
        self._timer_at = due
        precise = self._precise
        if precise is not None:  # the loop's time is CLOCK_MONOTONIC's (precise_timer.make)
            precise.arm(precise.now() + (due - self.clock.now()))
            self._timer = precise
            return
        # Wake TIMER_EARLY_S ahead: the selector rounds timeouts up to whole milliseconds.
        delay = max(0.0, due - self.clock.now() - TIMER_EARLY_S)
        shared = self._shared_timer
        if shared is None:
            self._timer = self._loop.call_later(delay, self._on_timer)
        else:  # the delay on the loop's scale: this simulator's clock need not be the loop's
            self._timer = shared.call_at(shared.time() + delay, self._on_timer)

    def _on_timer(self) -> None:
        self._timer = None
        self._timer_at = None
        self.pump()
        self._schedule()
