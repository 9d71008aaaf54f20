"""`topgimbal zenoh` over worker processes (cli/zenoh_workers.py): the cameras split into shares,
each served by a child process behind this process's Zenoh router, one key layout for subscribers;
the workers end with their parent, also when it is killed."""

from __future__ import annotations

import argparse
import asyncio
import json
import os
import signal
import sys
from pathlib import Path
from typing import Any

import pytest

from topgimbal.cli.zenoh_workers import refused_with_workers, shares, worker_count
from topgimbal.errors import FieldValueError

from .conftest import eventually, raw_call, raw_session
from .test_access import _acl_files

pytestmark = pytest.mark.loopback


def test_worker_count_holds_every_camera_and_refuses_too_few() -> None:
    assert worker_count(1000, 0, 256) == 4
    assert worker_count(256, 0, 256) == 1
    assert worker_count(3, 2, 256) == 2
    assert worker_count(3, 9, 256) == 3  # never a worker without cameras
    with pytest.raises(FieldValueError, match="at least 4"):
        worker_count(1000, 2, 256)
    with pytest.raises(FieldValueError, match="at most"):
        worker_count(5000, 0, 256)


def test_by_default_a_worker_takes_its_share_of_samples_and_no_more_workers_than_cores() -> None:
    from topgimbal.cli.zenoh_workers import SAMPLES_PER_WORKER
    from topgimbal.fleet.specs import MAX_CAMERAS

    assert SAMPLES_PER_WORKER == 50_000 and MAX_CAMERAS == 1024
    assert worker_count(1000, 0, MAX_CAMERAS, rate_hz=50, cpus=2) == 1  # 50,000 samples/s: one process
    assert worker_count(1000, 0, MAX_CAMERAS, rate_hz=100, cpus=2) == 2
    assert worker_count(1000, 0, MAX_CAMERAS, rate_hz=100, cpus=1) == 1  # one core: one process
    assert worker_count(3000, 0, MAX_CAMERAS, rate_hz=1, cpus=1) == 3  # the per-process cap still holds
    assert worker_count(4, 0, MAX_CAMERAS, rate_hz=1e9, cpus=64) == 4  # never a worker without cameras
    assert worker_count(1000, 3, MAX_CAMERAS, rate_hz=50, cpus=2) == 3  # --workers K: K


def test_shares_are_contiguous_and_even() -> None:
    got = shares(list(range(10)), 3)
    assert got == [[0, 1, 2, 3], [4, 5, 6], [7, 8, 9]]
    assert [x for s in got for x in s] == list(range(10))


def test_options_of_one_process_are_refused() -> None:
    args = argparse.Namespace(mavlink_keys=True, cot=None, status=None, config=None)
    assert "--mavlink-keys" in (refused_with_workers(args) or "")


def _children(pid: int) -> list[int]:
    out: list[int] = []
    for task in Path(f"/proc/{pid}/task").iterdir():
        out += [int(c) for c in (task / "children").read_text().split()]
    return out


def _alive(pid: int) -> bool:
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    stat = Path(f"/proc/{pid}/stat").read_text() if Path(f"/proc/{pid}/stat").exists() else ""
    return " Z " not in stat  # a zombie has ended


async def _start(tmp_path: Path, sims: Any, zport: int, names: list[str], *extra: str) -> asyncio.subprocess.Process:
    cams = await sims(len(names))
    path = tmp_path / "cameras.txt"
    path.write_text("".join(f"{n}={s.url},C12\n" for n, s in zip(names, cams, strict=True)))
    proc = await asyncio.create_subprocess_exec(
        sys.executable, "-m", "topgimbal.cli.main", "zenoh", "--cameras", str(path), "--workers", "2",
        "--listen", f"tcp/127.0.0.1:{zport}", *extra, stdout=asyncio.subprocess.PIPE, stderr=asyncio.subprocess.PIPE,
    )  # fmt: skip
    assert proc.stdout is not None
    line = await asyncio.wait_for(proc.stdout.readline(), 120)
    assert b"in 2 worker processes" in line, line + (await proc.stderr.read() if proc.stderr else b"")
    return proc


async def test_two_workers_serve_one_key_layout_and_stop_with_their_parent(
    tmp_path: Path, sims: Any, zport: int
) -> None:
    names = ["w0", "w1", "w2"]
    proc = await _start(tmp_path, sims, zport, names)
    workers = _children(proc.pid)
    assert len(workers) == 2
    session = await asyncio.to_thread(raw_session, zport)
    try:
        seen: dict[str, list[int]] = {}
        sub = session.declare_subscriber(
            "topgimbal/*/attitude",
            lambda s: seen.setdefault(str(s.key_expr), []).append(json.loads(s.payload.to_string())["seq"]),
        )
        await eventually(lambda: all(len(seen.get(f"topgimbal/{n}/attitude", [])) >= 10 for n in names), 60,
                         "attitude of every camera, whichever worker serves it")  # fmt: skip
        for n in names:  # a call reaches the camera in either worker
            replies = await asyncio.to_thread(raw_call, session, f"topgimbal/{n}/call/version", "{}")
            assert len(replies) == 1 and replies[0]["ok"], replies
        sub.undeclare()
    finally:
        session.close()
        proc.send_signal(signal.SIGINT)
        assert await asyncio.wait_for(proc.wait(), 60) == 0
    await eventually(lambda: not any(_alive(w) for w in workers), 30, "workers gone after the parent's stop")


async def test_workers_end_when_their_parent_is_killed(tmp_path: Path, sims: Any, zport: int) -> None:
    proc = await _start(tmp_path, sims, zport, ["k0", "k1"])
    workers = _children(proc.pid)
    assert len(workers) == 2 and all(_alive(w) for w in workers)
    proc.kill()  # no SIGINT to pass on: the workers see their parent gone
    await proc.wait()
    try:
        await eventually(lambda: not any(_alive(w) for w in workers), 60, "workers gone after the parent's kill")
    finally:
        for w in workers:
            if _alive(w):
                os.kill(w, signal.SIGKILL)


async def test_with_access_control_the_operator_reaches_every_worker_and_a_stranger_none(
    tmp_path: Path, sims: Any, zport: int
) -> None:
    """The router takes the --config file's access control; the workers its credentials."""
    import topgimbal

    server_conf, operator_conf = _acl_files(tmp_path)
    names = ["a0", "a1", "a2"]
    proc = await _start(tmp_path, sims, zport, names, "--config", str(server_conf))
    try:
        with pytest.raises(Exception, match="Unable to connect"):  # no credentials: no session
            await asyncio.to_thread(raw_session, zport)
        for n in names:  # each worker's cameras, through the router, with the operator's credentials
            url = f"zenoh/{n}?connect=tcp/127.0.0.1:{zport}&config={operator_conf}"
            async with topgimbal.connect(url) as cam:
                assert await cam.version()
    finally:
        proc.send_signal(signal.SIGINT)
        assert await asyncio.wait_for(proc.wait(), 60) == 0


async def test_options_of_one_process_and_too_few_workers_exit_2_before_serving(tmp_path: Path) -> None:
    path = tmp_path / "cameras.txt"
    path.write_text("".join(f"c{i}=udp://127.0.0.1:{6000 + i},C12\n" for i in range(1100)))
    for extra, said in ((["--mavlink-keys"], b"--mavlink-keys"), (["--workers", "1"], b"at least 2")):
        proc = await asyncio.create_subprocess_exec(
            sys.executable, "-m", "topgimbal.cli.main", "zenoh", "--cameras", str(path),
            "--listen", "tcp/127.0.0.1:1", *extra, stdout=asyncio.subprocess.PIPE, stderr=asyncio.subprocess.PIPE,
        )  # fmt: skip
        out, err = await asyncio.wait_for(proc.communicate(), 60)
        assert proc.returncode == 2 and said in err and b"Traceback" not in err, (extra, err)
        assert b"serving" not in out
