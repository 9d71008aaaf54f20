"""The batch key's timing and bounds (fleet/batch.py, issue 45), on a publisher double in virtual
time: a sample waits at most `batch_s`, a full batch goes at once, close sends what waits, and a put
Zenoh refuses is counted and logged, never raised into a camera's tap. The timing tests put on the
loop (`threaded=False`); the put thread a slow put hands the next ones to is tested below: it keeps
the order, never makes the loop wait for a put, past MAX_PENDING_PUTS drops the oldest batch, and
gives the puts back to the loop once none has been slow for THREAD_HOLD_S."""

from __future__ import annotations

import asyncio
import json
import logging
import threading
from typing import Any

import pytest

from topgimbal.client.state import GimbalAttitude
from topgimbal.clock import monotonic
from topgimbal.fleet.batch import (
    BATCH_KEYS,
    MAX_PUT_S,
    MAX_SAMPLES,
    PUT_SHARE,
    PUT_WINDOW_S,
    SOON_SAMPLES,
    THREAD_HOLD_S,
    AttitudeBatch,
    PutThread,
    batch_key,
    named,
)
from topgimbal.fleet.camera import attitude_json

pytestmark = pytest.mark.virtual


class Publisher:
    def __init__(self, key: str) -> None:
        self.key = key
        self.puts: list[tuple[float, str]] = []
        self.undeclared = False
        self.refuse: Exception | None = None

    def put(self, payload: str) -> None:
        if self.refuse is not None:
            raise self.refuse
        self.puts.append((monotonic(), payload))

    def undeclare(self) -> None:
        self.undeclared = True


class Session:
    def __init__(self) -> None:
        self.publishers: list[Publisher] = []

    def declare_publisher(self, key: str) -> Publisher:
        self.publishers.append(Publisher(key))
        return self.publishers[-1]


def sample(name: str, seq: int, yaw: float = 1.5) -> str:
    return named(name, attitude_json(GimbalAttitude(yaw, -20.25, 0.0, 0.0, 1764000000.5, "GAC"), seq))


async def test_samples_wait_at_most_batch_s_and_go_as_one_array() -> None:
    session = Session()
    batch = AttitudeBatch(session, "abc123", 0.005, threaded=False)
    pub = session.publishers[0]
    assert pub.key == batch_key("abc123") == "topgimbal/@attitude/abc123"
    t0 = monotonic()
    batch.add(sample("cam0", 1))
    await asyncio.sleep(0.002)
    batch.add(sample("cam1", 7, yaw=-3.0))
    await asyncio.sleep(0.0029)
    assert pub.puts == []  # the first sample has waited 4.9 ms
    await asyncio.sleep(0.0002)
    assert len(pub.puts) == 1 and pub.puts[0][0] - t0 == pytest.approx(0.005)
    got = json.loads(pub.puts[0][1])
    assert got == [
        {"name": "cam0", "yaw_deg": 1.5, "pitch_deg": -20.25, "roll_deg": 0.0, "t": 1764000000.5, "seq": 1},
        {"name": "cam1", "yaw_deg": -3.0, "pitch_deg": -20.25, "roll_deg": 0.0, "t": 1764000000.5, "seq": 7},
    ]
    # the next sample starts a new wait of its own
    await asyncio.sleep(0.1)
    batch.add(sample("cam0", 2))
    await asyncio.sleep(0.006)
    assert len(pub.puts) == 2 and pub.puts[1][0] - pub.puts[0][0] == pytest.approx(0.1051)
    assert (batch.puts, batch.samples) == (2, 3)


async def test_a_full_batch_goes_at_once_and_close_sends_what_waits() -> None:
    session = Session()
    batch = AttitudeBatch(session, "s", 1.0, threaded=False)
    pub = session.publishers[0]
    for i in range(MAX_SAMPLES + 3):
        batch.add(sample(f"cam{i % 1000}", i))
    assert len(pub.puts) == 1 and len(json.loads(pub.puts[0][1])) == MAX_SAMPLES
    batch.close()
    assert len(pub.puts) == 2 and [s["seq"] for s in json.loads(pub.puts[1][1])] == [
        MAX_SAMPLES,
        MAX_SAMPLES + 1,
        MAX_SAMPLES + 2,
    ]
    assert pub.undeclared
    batch.add(sample("cam0", 99))  # after close: dropped, no timer, no put
    await asyncio.sleep(2.0)
    assert len(pub.puts) == 2


async def test_a_refused_put_is_counted_and_logged_not_raised(caplog: Any) -> None:
    session = Session()
    batch = AttitudeBatch(session, "s", 0.01, threaded=False)
    pub = session.publishers[0]
    pub.refuse = RuntimeError("session closed")
    with caplog.at_level(logging.WARNING, logger="topgimbal.fleet"):
        for i in range(5):
            batch.add(sample("cam0", i))
            await asyncio.sleep(0.02)  # each one's timer fires, and its put fails
    assert batch.failed == 5 and batch.puts == 0
    lines = [r.getMessage() for r in caplog.records]
    assert len(lines) == 1, lines  # at most one line per 10 s
    assert "a batch of 1 samples was not put (session closed; 1 batches so far)" in lines[0]
    pub.refuse = None
    batch.add(sample("cam0", 9))
    await asyncio.sleep(0.02)
    assert batch.puts == 1 and json.loads(pub.puts[0][1])[0]["seq"] == 9


async def test_batch_s_out_of_range_is_refused() -> None:
    for bad in (0.0, 0.0005, 1.5, float("nan")):
        with pytest.raises(ValueError, match=r"expected 0.001..1.0 s"):
            AttitudeBatch(Session(), "s", bad)


def test_the_batch_key_is_beyond_every_cameras_wildcard() -> None:
    import zenoh

    batches = zenoh.KeyExpr(batch_key("0123abcd"))
    assert batches.intersects(zenoh.KeyExpr(BATCH_KEYS))
    for wildcard in ("topgimbal/**", "topgimbal/*/attitude", "topgimbal/*"):
        assert not batches.intersects(zenoh.KeyExpr(wildcard)), wildcard


async def test_a_sample_that_comes_after_batch_s_puts_the_batch_at_once() -> None:
    """The loop busy reading a burst: the timer has not run, but a sample arriving batch_s after
    the first one takes the batch out with it, not after the burst."""
    session = Session()
    batch = AttitudeBatch(session, "abc123", 0.005, threaded=False)
    pub = session.publishers[0]
    t0 = monotonic()
    batch.add(sample("cam0", 1), t0)
    batch.add(sample("cam1", 1), t0 + 0.004)  # still within the wait
    assert pub.puts == []
    batch.add(sample("cam2", 1), t0 + 0.005)  # arrived as the first one's wait ended
    assert len(pub.puts) == 1 and [d["name"] for d in json.loads(pub.puts[0][1])] == ["cam0", "cam1", "cam2"]
    batch.add(sample("cam0", 2), t0 + 0.006)  # the next batch's first: a wait of its own
    assert len(pub.puts) == 1
    await asyncio.sleep(0.006)
    assert len(pub.puts) == 2 and json.loads(pub.puts[1][1])[0]["seq"] == 2
    assert (batch.puts, batch.samples) == (2, 4)


async def test_a_batch_of_soon_samples_goes_when_the_current_callback_ends() -> None:
    """A read that brings SOON_SAMPLES samples or more (a loaded server): they are put once that
    read is over, in virtual time before any of them has waited; fewer wait for the timer."""
    session = Session()
    batch = AttitudeBatch(session, "abc123", 0.005, threaded=False)
    pub = session.publishers[0]
    t0 = monotonic()
    for i in range(SOON_SAMPLES - 1):  # one callback's worth, under the mark
        batch.add(sample(f"cam{i}", 1), t0)
    await asyncio.sleep(0)
    await asyncio.sleep(0.004)
    assert pub.puts == []  # the timer's wait, as before
    batch.add(sample("cam99", 1), t0 + 0.004)  # the mark reached: not put inside this callback
    assert pub.puts == []
    await asyncio.sleep(0)
    assert len(pub.puts) == 1 and pub.puts[0][0] - t0 == pytest.approx(0.004)
    assert len(json.loads(pub.puts[0][1])) == SOON_SAMPLES
    # the put cancelled the timer: nothing more at 5 ms, and the next batch waits afresh
    await asyncio.sleep(0.01)
    assert len(pub.puts) == 1
    for i in range(SOON_SAMPLES + 5):  # a longer read: one put after it, all of them
        batch.add(sample(f"cam{i}", 2), t0 + 0.014)
    await asyncio.sleep(0)
    assert len(pub.puts) == 2 and len(json.loads(pub.puts[1][1])) == SOON_SAMPLES + 5
    assert (batch.puts, batch.samples) == (2, 2 * SOON_SAMPLES + 5)


class Stuck(Publisher):
    """A publisher whose puts wait until `go` is set (Zenoh's queue to a subscriber that does not
    read), and say when one has started."""

    def __init__(self, key: str) -> None:
        super().__init__(key)
        self.go = threading.Event()
        self.started = threading.Event()

    def put(self, payload: str) -> None:
        self.started.set()
        assert self.go.wait(10.0), "the test never let the put go"
        super().put(payload)


def test_the_put_thread_keeps_the_order_and_never_makes_its_caller_wait(caplog: Any) -> None:
    pub = Stuck("k")
    sender = PutThread(pub, "k", max_pending=4)
    sender.submit("[0]", 1)
    assert pub.started.wait(10.0)  # the first put is under way, and stuck
    with caplog.at_level(logging.WARNING, logger="topgimbal.fleet"):
        for i in range(1, 8):  # submitted while it is stuck: none of these waits for it
            sender.submit(f"[{i}]", 10 * i)
    assert not pub.go.is_set() and pub.puts == []
    # 4 wait at most: [1], [2] and [3] were dropped unput, the oldest first
    assert sender.dropped == 10 + 20 + 30
    assert caplog.text.count("puts are behind") == 1  # then at most every 10 s
    assert "a batch of 10 samples was dropped unput (10 samples so far; at most 4 batches wait)" in caplog.text
    pub.go.set()
    assert sender.close()
    assert [p for _, p in pub.puts] == ["[0]", "[4]", "[5]", "[6]", "[7]"]
    assert (sender.puts, sender.samples, sender.failed) == (5, 1 + 40 + 50 + 60 + 70, 0)
    sender.submit("[8]", 1)  # after close: nothing
    assert len(pub.puts) == 5


def test_a_put_that_raises_on_the_thread_is_counted_and_the_next_one_goes(caplog: Any) -> None:
    pub = Publisher("k")
    pub.refuse = RuntimeError("session closed")
    sender = PutThread(pub, "k")
    with caplog.at_level(logging.WARNING, logger="topgimbal.fleet"):
        sender.submit("[1]", 3)
        assert sender.close()
    assert (sender.failed, sender.puts) == (1, 0)
    assert "a batch of 3 samples was not put (session closed; 1 batches so far)" in caplog.text
    pub.refuse = None
    again = PutThread(pub, "k")
    again.submit("[2]", 1)
    assert again.close() and [p for _, p in pub.puts] == ["[2]"]


def test_close_does_not_wait_for_a_put_stuck_beyond_its_bound() -> None:
    pub = Stuck("k")
    sender = PutThread(pub, "k")
    sender.submit("[1]", 1)
    assert pub.started.wait(10.0)
    assert sender.close(timeout_s=0.05) is False  # still stuck: close says so and returns
    pub.go.set()
    assert sender.close(timeout_s=10.0) and sender.puts == 1


class Clock:
    """The batch's put timer, moved by hand and by a put that takes `delay`."""

    def __init__(self) -> None:
        self.t = 0.0

    def __call__(self) -> float:
        return self.t


class Timed(Publisher):
    def __init__(self, key: str, clock: Clock) -> None:
        super().__init__(key)
        self.clock = clock
        self.delay = 0.0
        self.threads: list[str] = []  # where each put ran
        self.done = threading.Semaphore(0)

    def put(self, payload: str) -> None:
        self.threads.append(threading.current_thread().name)
        self.clock.t += self.delay
        super().put(payload)
        self.done.release()


async def test_puts_go_to_the_thread_when_the_loop_spends_too_long_in_them(caplog: Any) -> None:
    """A put of a few ms now and then (a busy host) keeps them on the loop; PUT_SHARE of a window
    spent in puts, or one put of MAX_PUT_S, hands them to the thread for THREAD_HOLD_S."""
    clock = Clock()
    pub = Timed("k", clock)
    session = Session()
    session.declare_publisher = lambda key: pub  # type: ignore[method-assign]
    batch = AttitudeBatch(session, "abc123", 0.005, clock=clock)  # threaded, as FleetServer makes it
    main = threading.current_thread().name

    async def one_batch() -> str:
        for i in range(SOON_SAMPLES):
            batch.add(sample(f"cam{i}", 1))
        await asyncio.sleep(0)  # handed over once this callback ends
        assert pub.done.acquire(timeout=10.0), "the batch was never put"
        return pub.threads[-1]

    pub.delay = 0.005  # a preempted put, once a window: stays on the loop
    for _ in range(5):
        assert await one_batch() == main
        clock.t += PUT_WINDOW_S
    assert batch.handovers == 0 and not batch.threaded_now
    # a subscriber that does not read: every put waits 4 ms
    pub.delay = 0.004
    needed = round(PUT_SHARE * PUT_WINDOW_S / pub.delay)
    with caplog.at_level(logging.WARNING, logger="topgimbal.fleet"):
        for _ in range(needed):
            assert await one_batch() == main
    assert batch.handovers == 1 and batch.threaded_now
    assert "the serving loop spent 200 ms in puts within 0.5 s" in caplog.text
    pub.delay = 0.0
    assert (await one_batch()).startswith("topgimbal-put")  # on the thread now
    clock.t += THREAD_HOLD_S  # its hold is over: back on the loop, which measures again
    assert not batch.threaded_now and await one_batch() == main
    pub.delay = MAX_PUT_S + 0.001  # one long put is enough
    assert await one_batch() == main
    assert batch.handovers == 2 and batch.threaded_now
    batch.close()
    n = 5 + needed + 3
    assert (batch.puts, batch.samples, batch.failed, batch.dropped) == (n, n * SOON_SAMPLES, 0, 0)
    assert [len(json.loads(p)) for _, p in pub.puts] == [SOON_SAMPLES] * n
