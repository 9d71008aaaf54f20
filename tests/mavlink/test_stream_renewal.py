"""Renewals of a UDP stream spread out (client/streams.py RENEW_SPREAD): clients started together,
as a fleet server starts its 1,000, asked again in the same loop turn every 20 s, which held that
server's loop for tens of milliseconds each time. Each wait is drawn from the period's last quarter:
never longer than `stream_renew_s` (a peer's lease is kept as before), never the same for all."""

from __future__ import annotations

import asyncio
import itertools

import pytest

import topgimbal
from topgimbal.client.streams import RENEW_SPREAD, renew_wait_s
from topgimbal.clock import monotonic

from .virtual import camera_input, in_virtual_time, start_camera

pytestmark = pytest.mark.virtual

CLIENTS = 16  # started in one loop turn; their first renewals all within one second: about 5e-10


def test_a_renewal_waits_within_the_periods_last_quarter() -> None:
    assert renew_wait_s(20.0, 0.0) == 20.0
    assert renew_wait_s(20.0, 0.5) == pytest.approx(20.0 * (1 - RENEW_SPREAD / 2))
    assert renew_wait_s(20.0, 0.999999) == pytest.approx(15.0, abs=1e-4)
    drawn = [renew_wait_s(20.0) for _ in range(1000)]
    assert min(drawn) >= 15.0 and max(drawn) <= 20.0
    assert max(drawn) - min(drawn) > 4.0  # drawn, not one value for everyone


@in_virtual_time
async def test_clients_started_together_renew_at_different_times() -> None:
    cams = [await start_camera("C12") for _ in range(CLIENTS)]
    heard = [camera_input(sim) for sim, _ in cams]
    t0 = monotonic()
    clients = await asyncio.gather(*(topgimbal.connect(url, model="C12", stream_renew_s=20.0) for _, url in cams))
    try:
        await asyncio.gather(*(c.attitude_stream(5) for c in clients))
        await asyncio.sleep(65.0)
        firsts = []
        for got in heard:
            gaa = [t - t0 for t, data in got if data[6:10] == b"wGAA"]
            gaps = [b - a for a, b in itertools.pairwise(gaa)]
            assert len(gaps) in (3, 4) and all(15.0 - 0.01 <= g <= 20.0 + 0.01 for g in gaps), gaa
            firsts.append(gaa[1])
        assert max(firsts) - min(firsts) > 1.0, sorted(firsts)  # not one loop turn for all
    finally:
        await asyncio.gather(*(c.close() for c in clients))
        await asyncio.gather(*(sim.stop() for sim, _ in cams))
