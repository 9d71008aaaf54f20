"""The batch key's timing and bounds (fleet/batch.py, issue 45), on a publisher double in virtual
time: a sample waits at most `batch_s`, a full batch goes at once, close sends what waits, and a put
Zenoh refuses is counted and logged, never raised into a camera's tap."""

from __future__ import annotations

import asyncio
import json
import logging
from typing import Any

import pytest

from topgimbal.client.state import GimbalAttitude
from topgimbal.clock import monotonic
from topgimbal.fleet.batch import BATCH_KEYS, MAX_SAMPLES, AttitudeBatch, batch_key, named
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
    batch = AttitudeBatch(session, "abc123", 0.005)
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
    batch = AttitudeBatch(session, "s", 1.0)
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
    batch = AttitudeBatch(session, "s", 0.01)
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
    batch = AttitudeBatch(session, "abc123", 0.005)
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
