"""A device that is another model than the client was told: once the model check says so, the
client sends nothing on its own initiative in the told model's dialect (no attitude stream request
again, no renewal, no ping, no host feed), says so in one line, and starts again if a later verdict
clears the device; and `detect_model()` (`--model auto`) asks every dialect without warning that
the placeholder model is wrong. Virtual tier: a simulator on `memory://`, on looptime."""

from __future__ import annotations

import asyncio
import contextlib
import itertools
import logging
import os
from typing import Any

import pytest

import topgimbal
from topgimbal.client.identity import Report
from topgimbal.clock import monotonic
from topgimbal.errors import TopGimbalError
from topgimbal.sim import Simulator

pytestmark = pytest.mark.virtual

_names = itertools.count()
NO_SOCKETS: dict[str, Any] = {"udp": []}  # the simulator serves only memory://


async def memory_camera(model: str) -> tuple[Simulator, str, list[tuple[float, bytes]]]:
    """A simulator on `memory://`, and every chunk it gets from now on, timed."""
    sim = await Simulator(model).start(**NO_SOCKETS)
    url = sim.listen_memory(f"quiet-{os.getpid()}-{next(_names)}")
    port = sim._memory[-1]
    inner = port.on_bytes
    assert inner is not None
    got: list[tuple[float, bytes]] = []

    def tap(data: bytes) -> None:
        got.append((monotonic(), data))
        inner(data)

    port.on_bytes = tap
    return sim, url, got


def idents(sent: list[tuple[float, bytes]], since: int = 0) -> list[str]:
    """What the chunks from `sent[since]` on were: "rVER", "wGAA"..."""
    return [data[6:10].decode() for _, data in sent[since:]]


async def test_a_wrong_model_gets_no_periodic_requests_until_the_verdict_clears_it(caplog: Any) -> None:
    caplog.set_level(logging.INFO, logger="topgimbal.client")
    sim, url, sent = await memory_camera("SIP")
    try:
        async with topgimbal.connect(url, model="C12", timeout_s=1.0) as cam:
            await cam.feed(lat_deg=47.0, lon_deg=8.0, alt_m=500.0)  # the C12's LAT/LON/ALT feeds, 2 Hz
            with contextlib.suppress(TopGimbalError):  # the SIP does not take a C12's stream request
                await cam.attitude_stream(50)
            verdict = await cam.wait_model_check(10.0)
            assert verdict.status == "mismatch" and verdict.fits == ("SIP",)
            at_verdict = len(sent)
            for _ in range(60):  # a minute of fresh fixes (as the bridge gives them) and the client's timers
                await cam.feed(lat_deg=47.0, lon_deg=8.0, alt_m=500.0)
                await asyncio.sleep(1.0)
            assert idents(sent, at_verdict) == [], idents(sent, at_verdict)
            assert cam.streams.halted and cam.feeds.halted and cam.streams.renewals == 0
            states = {v["state"] for v in cam.feeds.status()["feeds"].values()}  # type: ignore[attr-defined]
            assert states == {"stopped: the device is another model"}
            stops = [r for r in caplog.records if "stops sending" in r.getMessage()]
            assert len(stops) == 1 and "not a C12" in stops[0].getMessage()
            # a program's own request still goes out
            mark = len(sent)
            await cam.request("VER", read=True)
            assert idents(sent, mark) == ["rVER"]
            # a later model name that says C12 (a late MOD answer) clears it: the feeds and the
            # stream's request go out again
            cam.identity.add(Report("model_name", "MOD", "skydroid", "C12"))
            assert cam.model_check.status == "ok" and not cam.streams.halted and not cam.feeds.halted
            mark = len(sent)
            await asyncio.sleep(1.0)
            again = idents(sent, mark)
            assert {"wLAT", "wLON", "wALT", "wGAA"} <= set(again), again
    finally:
        await sim.stop()


async def test_detecting_the_model_is_quiet(caplog: Any) -> None:
    """A C20 asked as the stand-in C12 answers MOD with C20: detection's answer, not a warning."""
    caplog.set_level(logging.INFO, logger="topgimbal.client")
    for model in ("C20", "SIP", "C10"):
        sim, url, _sent = await memory_camera(model)
        try:
            async with topgimbal.connect(url, model="C12", timeout_s=0.5, check_model=False, host_feeds=False) as cam:
                assert await cam.detect_model() == model
                assert cam.model_check.status == "off"
        finally:
            await sim.stop()
    assert not [r.getMessage() for r in caplog.records if r.levelno >= logging.WARNING]
