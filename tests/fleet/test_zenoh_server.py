"""`topgimbal zenoh` as its own process serving three simulated cameras, seen by an independent
Zenoh program (eclipse-zenoh only): each camera's attitude under its name, a liveliness token per
camera, one camera pointed through its queryable while the others stay still, and hostile calls
answered with clear errors while the server goes on."""

from __future__ import annotations

import asyncio
import json
import os
import signal
import sys
from typing import Any

import pytest

from waiting import SETTLED_DEG, near

from .conftest import eventually, raw_call, raw_session

pytestmark = [pytest.mark.loopback, pytest.mark.integration]


async def _serve(args: list[str]) -> asyncio.subprocess.Process:
    proc = await asyncio.create_subprocess_exec(
        sys.executable, "-m", "topgimbal.cli.main", "zenoh", *args,
        stdout=asyncio.subprocess.PIPE, stderr=asyncio.subprocess.PIPE,
        preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_DFL),
    )  # fmt: skip
    assert proc.stdout is not None
    line = await asyncio.wait_for(proc.stdout.readline(), 60)
    assert b"serving" in line, line + (await proc.stderr.read() if proc.stderr else b"")
    return proc


async def _stop(proc: asyncio.subprocess.Process) -> int:
    if proc.returncode is None:
        proc.send_signal(signal.SIGINT)
        try:
            await asyncio.wait_for(proc.wait(), 30)
        except asyncio.TimeoutError:
            proc.kill()
            await proc.wait()
    return proc.returncode or 0


async def test_three_cameras_seen_and_one_pointed_by_an_independent_zenoh_client(sims: Any, zport: int) -> None:
    cams = await sims(3)
    names = ["north", "east", "south"]
    args = ["--listen", f"tcp/127.0.0.1:{zport}"]
    for name, sim in zip(names, cams, strict=True):
        args += ["--camera", f"{name}={sim.url},C12"]
    proc = await _serve(args)
    session = await asyncio.to_thread(raw_session, zport)
    try:
        seen: dict[str, list[dict[str, Any]]] = {}

        def on_attitude(sample: Any) -> None:
            seen.setdefault(str(sample.key_expr), []).append(json.loads(sample.payload.to_string()))

        sub = session.declare_subscriber("topgimbal/*/attitude", on_attitude)
        await eventually(lambda: all(len(seen.get(f"topgimbal/{n}/attitude", [])) >= 10 for n in names), 30,
                         "attitude of every camera")  # fmt: skip
        for n in names:
            sample = seen[f"topgimbal/{n}/attitude"][-1]
            assert set(sample) >= {"yaw_deg", "pitch_deg", "roll_deg", "t"}
            assert sample["yaw_deg"] == 0.0 and sample["pitch_deg"] == 0.0

        tokens = await asyncio.to_thread(
            lambda: [str(r.ok.key_expr) for r in session.liveliness().get("topgimbal/*", timeout=10) if r.ok]
        )
        assert sorted(tokens) == sorted(f"topgimbal/{n}" for n in names)

        # point "east" through its queryable; the reply is the attitude the camera reached
        replies = await asyncio.to_thread(raw_call, session, "topgimbal/east/call/point",
                                          json.dumps({"yaw_deg": 25.0, "pitch_deg": -30.0}), 60.0)  # fmt: skip
        assert len(replies) == 1 and replies[0]["ok"] is True, replies
        assert abs(replies[0]["result"]["yaw_deg"] - 25.0) <= 0.5
        # the simulator's live axes: point() confirmed the reported attitude within its 0.5 deg, the
        # physics may still be creeping the last hundredths: wait for them, never hold them to 0.5
        await near("camera east's yaw", lambda: cams[1].gimbal.yaw_deg, 25.0, margin=SETTLED_DEG, bound_s=30)
        await near("camera east's pitch", lambda: cams[1].gimbal.pitch_deg, -30.0, margin=SETTLED_DEG, bound_s=30)
        for still in (cams[0], cams[2]):
            assert still.gimbal.yaw_deg == 0.0 and still.gimbal.pitch_deg == 0.0
        # ... and its published attitude says so, under its own name only
        await eventually(lambda: abs(seen["topgimbal/east/attitude"][-1]["yaw_deg"] - 25.0) <= 0.5, 20)
        assert seen["topgimbal/north/attitude"][-1]["yaw_deg"] == 0.0
        assert seen["topgimbal/south/attitude"][-1]["yaw_deg"] == 0.0

        # hostile and mistaken calls: clear errors, nothing moves, the server goes on
        bad = {
            "topgimbal/north/call/launch": ("{}", "unknown_method"),
            "topgimbal/north/call/point": ('{"yaw_deg": 500, "pitch_deg": 0}', "value"),
            "topgimbal/south/call/set_angles": ('{"heading": 3}', "bad_request"),
            "topgimbal/south/call/zoom": ("not json", "bad_request"),
            "topgimbal/south/call/version": ("[1, 2]", "bad_request"),
            "topgimbal/north/call/photo": ("x" * 70000, "bad_request"),
        }
        for key, (payload, kind) in bad.items():
            got = await asyncio.to_thread(raw_call, session, key, payload, 20.0)
            assert len(got) == 1 and got[0]["ok"] is False and got[0]["kind"] == kind, (key, got)
            assert got[0]["error"]
        assert cams[0].gimbal.yaw_deg == 0.0 and cams[0].camera.photos_taken == 0
        # a wildcard call would act on several cameras: refused by each
        got = await asyncio.to_thread(raw_call, session, "topgimbal/*/call/photo", "{}", 20.0)
        assert got and all(r["ok"] is False for r in got)
        assert all(c.camera.photos_taken == 0 for c in cams)
        ok = await asyncio.to_thread(raw_call, session, "topgimbal/south/call/version", "{}", 20.0)
        assert ok[0]["ok"] is True and isinstance(ok[0]["result"], str)
        sub.undeclare()
    finally:
        session.close()
        assert await _stop(proc) == 0


async def test_usage_errors_exit_2(sims: Any) -> None:
    (sim,) = await sims(1)
    cases = [
        ["--listen", "tcp/127.0.0.1:7447"],  # no camera
        ["--camera", f"a={sim.url},C12"],  # no endpoint
        ["--camera", "a b=udp://127.0.0.1:1,C12", "--listen", "tcp/127.0.0.1:7447"],
        ["--camera", "a=udp://127.0.0.1:1,NOPE", "--listen", "tcp/127.0.0.1:7447"],
        ["--camera", f"a={sim.url},C12", "--listen", "127.0.0.1:7447"],
        ["--camera", f"a={sim.url},C12", "--listen", "tcp/127.0.0.1:7447", "--rate-hz", "0"],
    ]
    for args in cases:
        proc = await asyncio.create_subprocess_exec(
            sys.executable, "-m", "topgimbal.cli.main", "zenoh", *args,
            stdout=asyncio.subprocess.PIPE, stderr=asyncio.subprocess.PIPE, env={**os.environ},
        )  # fmt: skip
        _out, err = await asyncio.wait_for(proc.communicate(), 60)
        assert proc.returncode == 2, (args, err)
        assert b"Traceback" not in err and err.strip(), (args, err)
