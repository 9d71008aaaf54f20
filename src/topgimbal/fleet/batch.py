"""Many cameras' attitude samples in one Zenoh put: `topgimbal/@attitude/<server id>` (issue 45).

A subscriber of every camera's `topgimbal/<name>/attitude` gets one Zenoh sample, and runs one
callback, per camera per frame: 50,000 a second for 1,000 cameras at 50 Hz, more than a Python
program keeps up with beside its server, and each one costs the server a put to that subscriber.
The batch key carries the same samples, each the per-camera JSON with the camera's `name` first,
as one JSON array per put: every `batch_s` (the first sample of a batch starts the wait, so a
sample waits at most that long), when the loop's current callback ends once SOON_SAMPLES are
waiting (a loaded server's read), or at once when MAX_SAMPLES are waiting.

A put waits while Zenoh's queue to a subscriber is full (a subscriber that does not read): on the
serving loop that stops every camera's reads and calls (in one run the loop stood still for a
second and the kernel dropped 17,262 camera datagrams). So once the loop has spent PUT_SHARE of a
PUT_WINDOW_S in puts (or one put took MAX_PUT_S), the puts go to a thread of their own
(`PutThread`) for THREAD_HOLD_S, then back to the loop, which measures again: the loop
hands each batch over and goes on; at most MAX_PENDING_PUTS batches wait for the thread, then the
oldest is dropped, counted and logged. One slow subscriber loses samples; the cameras' reads and
calls do not stop. (Zenoh's put lets other threads run while it waits.) Puts are on the loop
otherwise: a handover to a thread waits for the interpreter lock, which the busy loop holds, and
added 0.2-1.0 ms to a sample's median when every put went through it. One slow put is not enough:
on a busy host a put now and then takes 2-5 ms (preempted), and the thread, whose puts wait for
that lock too, would never look fast again.

The key's second chunk starts with '@': a verbatim chunk in Zenoh, which no wildcard matches, so
a subscriber of `topgimbal/**` (a console, a recorder) never gets batches it did not ask for.
Subscribe to `topgimbal/@attitude/*`: one key per serving process (its Zenoh session id), so
`topgimbal zenoh --workers K` puts K batch streams. The per-camera keys are published as before.
"""

from __future__ import annotations

import asyncio
import logging
import math
import threading
from collections import deque
from typing import Any

from ..client.remote_keys import ROOT
from ..clock import MonotonicFn, monotonic
from ..logthrottle import ThrottledLog

log = logging.getLogger("topgimbal.fleet")

BATCH_CHUNK = "@attitude"
BATCH_KEYS = f"{ROOT}/{BATCH_CHUNK}/*"  # what a subscriber of every server's batches asks for
# 2 ms: at 1,000 cameras x 50 Hz, 540 puts a second instead of 5 ms's 190, for 0.3-0.4 us more of the
# server's CPU a sample (18.2 against 17.8-17.9) and half the wait (a sample's median from camera
# to subscriber 1.3-1.6 ms instead of 2.9-3.4; docs/fleet.md, 2026-11-30)
DEFAULT_BATCH_S = 0.002
MIN_BATCH_S, MAX_BATCH_S = 0.001, 1.0
MAX_SAMPLES = 4096  # samples in one put at most (about 450 KiB): more are put at once
# A batch that holds this many goes when the loop's current callback (a read of the shared socket)
# ends, not when its first sample has waited batch_s: under load a read brings dozens of samples,
# each put is then as full as a put needs to be, and the wait was most of a sample's time in the
# server (docs/fleet.md, "ninth round"). Under it (a light load) the timer gathers them as before.
SOON_SAMPLES = 32
# Batches handed to the put thread and not yet put: 64 is about 0.1 s of puts at 1,000 cameras
# (600 a second), a few MiB at most; past it the oldest batch waiting is dropped (a subscriber
# that slow loses samples either way: Zenoh drops a put it cannot queue in time).
MAX_PENDING_PUTS = 64
PUT_THREAD_JOIN_S = 2.0  # at close, for the puts still waiting
# The loop's share of time in puts that hands them to the thread: 500-600 puts a second at 1,000
# cameras took 4-15 % of it (unpinned, beside the simulators); a subscriber that does not read made
# each wait 3.8-5.1 ms on average, up to 11.7 ms, in a test of Zenoh alone.
PUT_WINDOW_S = 0.5
PUT_SHARE = 0.4
MAX_PUT_S = 0.05  # one put that long does too (a large batch, fragmented, waits up to 50 ms in Zenoh)
THREAD_HOLD_S = 5.0  # how long the thread then keeps the puts


def batch_key(server_id: str) -> str:
    return f"{ROOT}/{BATCH_CHUNK}/{server_id}"


def batch_head(name: str) -> str:
    """How a camera's sample opens on the batch key: `{"name":"NAME",`. Camera names are checked
    on the way in (remote_keys.NAME_RE: letters, digits, '_', '-', '.'), so nothing needs escaping."""
    return f'{{"name":"{name}",'


def named(name: str, sample_json: str) -> str:
    """A camera's attitude JSON (`{"yaw_deg":...}`) with `"name"` first (`batch_head`)."""
    return batch_head(name) + sample_json[1:]


class PutThread:
    """Puts payloads on a publisher from a thread of its own, in the order given. `submit` (any
    thread) never waits: past MAX_PENDING_PUTS waiting, the oldest is dropped and counted.
    Counters: `puts`, `samples` (in batches put), `failed` (puts Zenoh refused), `dropped`
    (samples in batches dropped unput)."""

    def __init__(self, pub: Any, key: str, max_pending: int = MAX_PENDING_PUTS) -> None:
        self._pub = pub
        self.key = key
        self.max_pending = max_pending
        self._pending: deque[tuple[str, int]] = deque()
        self._cv = threading.Condition()
        self._stopping = False
        self._putting = False
        self.puts = 0
        self.samples = 0
        self.failed = 0
        self.dropped = 0
        self._throttle = ThrottledLog(log, 10.0)
        self._thread = threading.Thread(target=self._run, name=f"topgimbal-put {key}", daemon=True)
        self._thread.start()

    def submit(self, payload: str, samples: int) -> None:
        with self._cv:
            if self._stopping:
                return
            if len(self._pending) >= self.max_pending:
                _, lost = self._pending.popleft()
                self.dropped += lost
                if self._throttle.allow("behind") is not None:
                    log.warning("%s: puts are behind (a subscriber that does not read?): a batch of %d samples "
                                "was dropped unput (%d samples so far; at most %d batches wait)", self.key, lost,
                                self.dropped, self.max_pending)  # fmt: skip
            self._pending.append((payload, samples))
            self._cv.notify()

    @property
    def busy(self) -> bool:
        """A batch waits or is being put: a put made elsewhere now would overtake it."""
        return self._putting or bool(self._pending)

    def _run(self) -> None:
        while True:
            with self._cv:
                while not self._pending and not self._stopping:
                    self._cv.wait()
                if not self._pending:
                    return
                # busy before the queue looks empty: the loop reads `busy` without the lock, and a
                # put of its own between the two would overtake this one
                self._putting = True
                payload, samples = self._pending.popleft()
            try:
                self._pub.put(payload)
            except Exception as exc:  # never an unexpected error: counted and logged
                self.failed += 1
                if self._throttle.allow("put") is not None:
                    log.warning("%s: a batch of %d samples was not put (%s; %d batches so far)", self.key, samples,
                                exc, self.failed)  # fmt: skip
                continue
            else:
                self.puts += 1
                self.samples += samples
            finally:
                self._putting = False

    def close(self, timeout_s: float = PUT_THREAD_JOIN_S) -> bool:
        """Put what waits (within `timeout_s`), then end the thread; False if it had not ended."""
        with self._cv:
            self._stopping = True
            self._cv.notify()
        self._thread.join(timeout_s)
        return not self._thread.is_alive()


class AttitudeBatch:
    """Collects samples on the serving loop and puts them as one JSON array. Sync, loop-bound: `add`
    is called from the cameras' attitude taps, on the loop the batch was made on. `threaded=False`:
    no put thread to hand slow puts to (every put on the loop). `clock` times the puts."""

    def __init__(
        self,
        session: Any,
        server_id: str,
        batch_s: float = DEFAULT_BATCH_S,
        *,
        threaded: bool = True,
        clock: MonotonicFn = monotonic,
    ) -> None:
        if not MIN_BATCH_S <= batch_s <= MAX_BATCH_S:
            raise ValueError(f"batch_s {batch_s!r}: expected {MIN_BATCH_S}..{MAX_BATCH_S} s")
        self.key = batch_key(server_id)
        self.batch_s = batch_s
        self._loop = asyncio.get_running_loop()
        self._pub = session.declare_publisher(self.key)
        self._lines: list[str] = []
        self._first_t: float | None = None  # when the first sample waiting arrived (add's `t`)
        self._timer: asyncio.TimerHandle | None = None
        self._soon: asyncio.Handle | None = None  # the put after the current callback (SOON_SAMPLES)
        self._closed = False
        self._clock = clock
        self._sender: PutThread | None = PutThread(self._pub, self.key) if threaded else None
        self._thread_until = -math.inf  # puts go through the thread until then (self._clock)
        self._window_at = -math.inf  # the current PUT_WINDOW_S began then
        self._window_put_s = 0.0  # time in puts on the loop in it
        self.handovers = 0  # times the puts went to the thread
        self._puts = 0  # on the loop
        self._samples = 0
        self._failed = 0  # puts Zenoh refused (a closing session): their samples are not sent
        self._throttle = ThrottledLog(log, 10.0)

    # Counters: on the loop and on the put thread together (read them after close() for final figures).
    @property
    def puts(self) -> int:
        return self._puts + (self._sender.puts if self._sender is not None else 0)

    @property
    def samples(self) -> int:
        return self._samples + (self._sender.samples if self._sender is not None else 0)

    @property
    def failed(self) -> int:
        return self._failed + (self._sender.failed if self._sender is not None else 0)

    @property
    def threaded_now(self) -> bool:
        """Whether the next put goes through the put thread (the loop's puts were slow lately)."""
        return self._sender is not None and (self._sender.busy or self._clock() < self._thread_until)

    @property
    def dropped(self) -> int:
        """Samples in batches dropped because the put thread was MAX_PENDING_PUTS behind."""
        return self._sender.dropped if self._sender is not None else 0

    def add(self, line: str, t: float | None = None) -> None:
        """`t`: when the sample arrived, on the loop's clock. A sample that comes when the batch's
        first one has waited `batch_s` already puts the batch at once: while the loop reads a
        burst of datagrams (256 at a time, several milliseconds in a busy worker) the timer cannot
        run, and the batch would wait for the whole burst."""
        if self._closed:
            return
        lines = self._lines
        lines.append(line)
        if len(lines) == 1:
            self._first_t = t
        n = len(lines)
        if n >= MAX_SAMPLES or (t is not None and self._first_t is not None and t - self._first_t >= self.batch_s):
            self.flush()
            return
        if self._timer is None:
            self._timer = self._loop.call_later(self.batch_s, self.flush)
        if n >= SOON_SAMPLES and self._soon is None:
            self._soon = self._loop.call_soon(self.flush)

    def flush(self) -> None:
        if self._timer is not None:
            self._timer.cancel()
            self._timer = None
        if self._soon is not None:
            self._soon.cancel()
            self._soon = None
        lines = self._lines
        if not lines:
            return
        self._lines = []
        payload = "[" + ",".join(lines) + "]"
        sender = self._sender
        t0 = self._clock()
        if sender is not None and (sender.busy or t0 < self._thread_until):
            sender.submit(payload, len(lines))
            return
        try:
            self._pub.put(payload)
        except Exception as exc:  # from a timer or a camera's tap: never an unexpected error
            self._failed += 1
            if self._throttle.allow("put") is not None:
                log.warning("%s: a batch of %d samples was not put (%s; %d batches so far)", self.key, len(lines),
                            exc, self._failed)  # fmt: skip
            return
        finally:
            if sender is not None:
                self._measure(t0, self._clock() - t0)
        self._puts += 1
        self._samples += len(lines)

    def _measure(self, t0: float, took: float) -> None:
        """Count a put on the loop that began at `t0` and took `took`; past PUT_SHARE of the
        window (or one put of MAX_PUT_S), the next puts go to the thread for THREAD_HOLD_S."""
        if t0 - self._window_at >= PUT_WINDOW_S:
            self._window_at, self._window_put_s = t0, 0.0
        self._window_put_s += took
        spent = self._window_put_s
        if spent < PUT_SHARE * PUT_WINDOW_S and took < MAX_PUT_S:
            return
        self._thread_until = t0 + took + THREAD_HOLD_S
        self._window_at, self._window_put_s = -math.inf, 0.0
        self.handovers += 1
        if self._throttle.allow("slow") is not None:
            log.warning("%s: the serving loop spent %.0f ms in puts within %g s (a subscriber that does not read?); "
                        "puts go through a thread of their own for %g s (%d times so far)", self.key, spent * 1000,
                        PUT_WINDOW_S, THREAD_HOLD_S, self.handovers)  # fmt: skip

    def close(self) -> None:
        """What is waiting goes out; then the publisher is undeclared (a closed session: nothing)."""
        if self._closed:
            return
        try:
            self.flush()
        finally:
            self._closed = True
            if self._sender is not None and not self._sender.close():
                log.warning("%s: puts still waiting after %g s at close", self.key, PUT_THREAD_JOIN_S)
            try:
                self._pub.undeclare()
            except Exception:  # the session closed first: its declarations went with it
                pass
