"""The batch key served by `topgimbal zenoh` (fleet/batch.py, issue 45), read by an independent
Zenoh program (eclipse-zenoh only): every camera's samples, none lost or repeated, several to a
put; one key per serving process with worker processes; and nothing of it on a `topgimbal/**`
subscriber, which gets the per-camera keys as before."""

from __future__ import annotations

import asyncio
import itertools
import json
import sys
from typing import Any

import pytest

from topgimbal.fleet.batch import BATCH_KEYS

from .conftest import eventually, raw_session
from .test_zenoh_server import _serve, _stop

pytestmark = [pytest.mark.loopback, pytest.mark.integration]


class Batches:
    """Every batch heard, by key; each camera's seq numbers in the order they came."""

    def __init__(self) -> None:
        self.sizes: dict[str, list[int]] = {}
        self.seqs: dict[str, list[int]] = {}
        self.keys_of: dict[str, set[str]] = {}

    def __call__(self, sample: Any) -> None:
        key = str(sample.key_expr)
        rows = json.loads(sample.payload.to_string())
        self.sizes.setdefault(key, []).append(len(rows))
        for row in rows:
            assert set(row) == {"name", "yaw_deg", "pitch_deg", "roll_deg", "t", "seq"}, row
            self.seqs.setdefault(row["name"], []).append(row["seq"])
            self.keys_of.setdefault(row["name"], set()).add(key)


def gaps(seqs: list[int]) -> list[tuple[int, int]]:
    return [(a, b) for a, b in itertools.pairwise(seqs) if b != a + 1]


async def _heard(args: list[str], zport: int, names: list[str]) -> tuple[Batches, list[str]]:
    proc = await _serve([*args, "--listen", f"tcp/127.0.0.1:{zport}"])
    session = await asyncio.to_thread(raw_session, zport)
    try:
        batches = Batches()
        everything: list[str] = []
        subs = [session.declare_subscriber(BATCH_KEYS, batches),
                session.declare_subscriber("topgimbal/**", lambda s: everything.append(str(s.key_expr)))]  # fmt: skip
        await eventually(lambda: all(len(batches.seqs.get(n, [])) >= 60 for n in names), 60,
                         "60 batched samples of every camera")  # fmt: skip
        for sub in subs:
            sub.undeclare()
        return batches, everything
    finally:
        session.close()
        assert await _stop(proc) == 0


async def test_every_cameras_samples_come_batched(sims: Any, zport: int) -> None:
    cams = await sims(3)
    names = ["north", "east", "south"]
    args = ["--batch-ms", "50"]
    for name, sim in zip(names, cams, strict=True):
        args += ["--camera", f"{name}={sim.url},C12"]
    batches, everything = await _heard(args, zport, names)
    assert len(batches.sizes) == 1  # one serving process, one key
    for n in names:
        seqs = batches.seqs[n]
        assert gaps(seqs) == [], (n, gaps(seqs))  # none lost, repeated or out of order
    sizes = [s for ss in batches.sizes.values() for s in ss]
    # 3 cameras at 50 Hz put every 50 ms or so: several samples to a put, not one each
    assert sum(sizes) / len(sizes) >= 3, sizes
    assert everything and not [k for k in everything if "@" in k]
    assert {k for k in everything if k.endswith("/attitude")} == {f"topgimbal/{n}/attitude" for n in names}


async def test_worker_processes_put_a_batch_key_each(sims: Any, zport: int) -> None:
    cams = await sims(4)
    names = [f"cam{i}" for i in range(4)]
    args = ["--workers", "2"]
    for name, sim in zip(names, cams, strict=True):
        args += ["--camera", f"{name}={sim.url},C12"]
    batches, _ = await _heard(args, zport, names)
    assert len(batches.sizes) == 2, sorted(batches.sizes)
    for n in names:
        assert len(batches.keys_of[n]) == 1, (n, batches.keys_of[n])  # a camera is one worker's
        assert gaps(batches.seqs[n]) == [], (n, gaps(batches.seqs[n]))
    assert {k for ks in batches.keys_of.values() for k in ks} == set(batches.sizes)


@pytest.mark.parametrize("bad", ["0.5", "1001", "x", "nan"])
async def test_a_bad_batch_ms_is_a_usage_error(sims: Any, zport: int, bad: str) -> None:
    (sim,) = await sims(1)
    proc = await asyncio.create_subprocess_exec(
        sys.executable, "-m", "topgimbal.cli.main", "zenoh", "--camera", f"a={sim.url},C12",
        "--listen", f"tcp/127.0.0.1:{zport}", "--batch-ms", bad,
        stdout=asyncio.subprocess.PIPE, stderr=asyncio.subprocess.PIPE,
    )  # fmt: skip
    _out, err = await asyncio.wait_for(proc.communicate(), 60)
    assert proc.returncode == 2, err
    assert f"--batch-ms: {bad!r}: expected 0 (no batch key) or 1..1000 ms".encode() in err, err


def test_the_cli_default_batch_wait_is_the_servers() -> None:
    """`topgimbal zenoh` without --batch-ms waits what FleetServer does (fleet/batch.py), and says so."""
    import argparse

    from topgimbal.cli import zenoh_cmd
    from topgimbal.fleet.batch import DEFAULT_BATCH_S

    top = argparse.ArgumentParser()
    zenoh_cmd.register(top.add_subparsers())
    args = top.parse_args(["zenoh", "--camera", "a=udp://127.0.0.1:5000,C12"])
    assert args.batch_ms == DEFAULT_BATCH_S * 1000
    sub = next(a for a in top._actions if isinstance(a, argparse._SubParsersAction)).choices["zenoh"]
    assert f"(default {DEFAULT_BATCH_S * 1000:g}; 0: no batch key)" in " ".join(sub.format_help().split())
