"""A discrete-event model of a lossy link and a device, to drive the transaction engine on a fake
clock: every packet is dropped, delayed (0..max_delay_s on top of the base delay, which reorders),
duplicated (the copy arrives together with the original, and the device answers a copied request
together with the original's answer), truncated (delivered as a frame with a wrong length
character, as the parser recovers it) or refused by the device (ERE). The device records what it
held when, so each outcome can be checked against the truth."""

from __future__ import annotations

import heapq
import itertools
import random
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

from topgimbal.client.engine import Engine, Transaction
from topgimbal.errors import DeviceError
from topgimbal.protocol import Frame, get_model

DIALECT, MODEL = get_model("C12")
BASE_DELAY_S = 0.001  # one way; every round trip is at least twice this
ADDRESSES = [f"10.0.0.{i}" for i in range(1, 9)]
REFUSED = "10.0.0.9"  # the device answers ERE to this one


@dataclass
class Faults:
    drop: float = 0.0
    duplicate: float = 0.0
    truncate: float = 0.0
    max_delay_s: float = 0.0  # extra one-way delay, uniform; reorders packets
    late_p: float = 0.0  # probability that a packet gets the full max_delay_s


@dataclass
class Op:
    kind: str  # read | write | photo | refused
    worker: int
    value: str | None = None
    start: float = 0.0
    end: float | None = None
    tx: Transaction | None = None


@dataclass
class Device:
    value: str = ADDRESSES[0]
    history: list[tuple[float, str]] = field(default_factory=lambda: [(0.0, ADDRESSES[0])])
    photos: int = 0
    photo_frames: dict[int, int] = field(default_factory=dict)  # tx id -> CAP frames applied
    refused: set[int] = field(default_factory=set)  # tx ids whose frame got ERE

    def held_between(self, a: float, b: float) -> set[str]:
        held = {v for t, v in self.history if a <= t <= b}
        before = [v for t, v in self.history if t < a]
        if before:
            held.add(before[-1])
        return held


class World:
    def __init__(self, faults: Faults, seed: int, *, late_window_s: float, timeout_s: float, retries: int) -> None:
        self.now = 0.0
        self.rng = random.Random(seed)
        self.faults = faults
        self.events: list[tuple[float, int, Callable[[], None]]] = []
        self.seq = itertools.count()
        self.engine = Engine(clock=lambda: self.now, late_window_s=late_window_s, dup_window_s=0.05)
        self.device = Device()
        self.timeout_s = timeout_s
        self.retries = retries
        self.ops: list[Op] = []
        self.tick_at: float | None = None
        self.sent_by_tx: dict[int, int] = {}

    # -- scheduling ------------------------------------------------------------------------------

    def at(self, t: float, fn: Callable[[], None]) -> None:
        heapq.heappush(self.events, (t, next(self.seq), fn))

    def run(self, until: float) -> None:
        while self.events and self.events[0][0] <= until:
            t, _, fn = heapq.heappop(self.events)
            self.now = max(self.now, t)
            fn()
            self.pump()

    def pump(self) -> None:
        for frame in self.engine.take_frames():
            tx = self._owner(frame)
            self.sent_by_tx[tx] = self.sent_by_tx.get(tx, 0) + 1
            self._transmit(frame, tx)
        for tx in self.engine.take_finished():
            op = tx.waiter
            if isinstance(op, Op) and op.end is None:
                op.end = self.now
                self._next_op(op.worker)
        d = self.engine.next_deadline()
        if d is not None and d != self.tick_at:
            self.tick_at = d
            self.at(d, self._tick)

    def _tick(self) -> None:
        self.tick_at = None
        self.engine.on_tick()

    def _owner(self, frame: Frame) -> int:
        # the engine's newest transaction whose frame this is (frames of one tx are identical)
        for tx in reversed(self._txs):
            if tx.frame is frame:
                return tx.id
        return -1

    # -- the link ---------------------------------------------------------------------------------

    def _delay(self) -> float:
        f = self.faults
        extra = f.max_delay_s if self.rng.random() < f.late_p else self.rng.random() * f.max_delay_s
        return BASE_DELAY_S + extra

    def _transmit(self, frame: Frame, tx: int) -> None:
        """A request on its way: the delay of its answer is drawn here, so that the device's
        answers to two copies of one request travel together, as the copies did."""
        f = self.faults
        if self.rng.random() < f.drop:
            return
        t = self.now + self._delay()
        back = self._delay()
        self.at(t, lambda: self._device_receives(frame, tx, back))
        if self.rng.random() < f.duplicate:
            self.at(t + 1e-7, lambda: self._device_receives(frame, tx, back))

    def _device_receives(self, frame: Frame, tx: int, back: float) -> None:
        f = self.faults
        for reply in self._device_handle(frame, tx):
            if self.rng.random() < f.drop:
                continue
            if self.rng.random() < f.truncate and len(reply.data) > 1:
                reply = reply._replace(data=reply.data[:-1], declared_length=len(reply.data))
            t = self.now + back
            self.at(t, lambda r=reply: self._host_receives(r))
            if self.rng.random() < f.duplicate:
                self.at(t + 1e-7, lambda r=reply: self._host_receives(r))

    def _device_handle(self, frame: Frame, tx: int) -> list[Frame]:
        dev = self.device
        if frame.ident == "IPV" and frame.rw == "r":
            return [DIALECT.response(frame, address=dev.value)]
        if frame.ident == "IPV":
            value = frame.data.decode()
            if value == REFUSED:
                dev.refused.add(tx)
                return [Frame("#TP", frame.dst, frame.src, "w", "ERE", b"!!")]
            dev.value = value
            dev.history.append((self.now, value))
            return [frame.swapped()]
        if frame.ident == "CAP":
            dev.photos += 1
            dev.photo_frames[tx] = dev.photo_frames.get(tx, 0) + 1
            return [frame.swapped()]
        return []

    def _host_receives(self, frame: Frame) -> None:
        self.engine.on_message(DIALECT.decode(frame))

    # -- the host's workers -----------------------------------------------------------------------

    def start(self, scripts: list[list[Op]]) -> None:
        self._txs: list[Transaction] = []
        self._scripts = {i: list(s) for i, s in enumerate(scripts)}
        for w in self._scripts:
            self.at(0.0, lambda w=w: self._next_op(w))

    def _next_op(self, worker: int) -> None:
        script = self._scripts[worker]
        if not script:
            return
        op = script.pop(0)
        self.at(self.now + self.rng.random() * 0.01, lambda: self._begin(op))

    def _begin(self, op: Op) -> None:
        op.start = self.now
        self.ops.append(op)
        if op.kind == "read":
            frame = DIALECT.encode("IPV", read=True)
            tx = self.engine.submit(frame, timeout_s=self.timeout_s, retries=self.retries)
        elif op.kind in ("write", "refused"):
            frame = DIALECT.encode("IPV", address=op.value)
            tx = self.engine.submit(frame, timeout_s=self.timeout_s, retries=self.retries)
        else:
            frame = DIALECT.encode("CAP")
            tx = self.engine.submit(frame, timeout_s=self.timeout_s, retries=self.retries, exclusive=True)
        tx.waiter = op
        op.tx = tx
        self._txs.append(tx)


def check_contract(world: World) -> dict[str, Any]:
    """Assert the client's contract for every finished operation; return counts."""
    dev = world.device
    counts = {"ok": 0, "failed": 0, "reads_ok": 0, "photos_acked": 0}
    write_values = [op.value for op in world.ops if op.kind == "write"]
    for op in world.ops:
        tx = op.tx
        assert tx is not None and tx.done, f"{op} never finished"
        assert op.end is not None
        if tx.error is not None:
            counts["failed"] += 1
            if isinstance(tx.error, DeviceError) and "refused" in str(tx.error):
                assert tx.id in dev.refused, f"{op}: ERE of another request given to it: {tx.error}"
            continue
        counts["ok"] += 1
        reply = tx.reply
        assert reply is not None and reply.frame.declared_length is None
        if op.kind == "read":
            counts["reads_ok"] += 1
            got = reply.fields["address"]
            held = dev.held_between(op.start, op.end)
            assert got in held, f"read returned {got} at {op.start:.4f}..{op.end:.4f}; device held {held}"
        elif op.kind == "write":
            assert reply.frame.data == tx.frame.data
            assert any(v == op.value for _, v in dev.history), "write acknowledged but never applied"
            if write_values.count(op.value) == 1:  # only this call ever asked for it
                first = tx.first_sent_at or op.start
                assert op.value in dev.held_between(first, op.end), f"{op.value} not applied during the call"
        elif op.kind == "refused":
            raise AssertionError(f"a refused write succeeded: {reply.frame}")
        else:
            counts["photos_acked"] += 1
            assert dev.photo_frames.get(tx.id, 0) >= 1, "a photo acknowledged whose frame the device never got"
    for op in world.ops:
        if op.kind == "photo":
            assert world.sent_by_tx.get(op.tx.id, 0) == 1, "a photo frame was sent more than once"
    return counts
