"""Attitude streams stop deterministically when their consumer leaves, and `point()` works after
the README's own telemetry pattern (issue 17, item 1)."""

from __future__ import annotations

import asyncio

import pytest

import topgimbal

from .test_client_link import until

pytestmark = pytest.mark.loopback


def gaa_rates(frames) -> list[int]:
    return [int(f.data, 16) for f in frames if f.ident == "GAA" and f.rw == "w"]


@pytest.mark.integration
async def test_point_works_right_after_breaking_out_of_an_attitude_loop(sim_factory):
    sim = await sim_factory("C12", seed=31)
    async with topgimbal.connect(dict(sim.endpoints)["udp"], model="C12", timeout_s=0.5) as cam:
        async for _att in cam.attitude(rate_hz=20):
            break
        att = await cam.point(5, -5)
        assert abs(att.yaw_deg - 5) <= 0.5 and abs(att.pitch_deg + 5) <= 0.5
        got = await cam.get_attitude()
        assert abs(got.yaw_deg - 5) <= 0.5


@pytest.mark.integration
def test_a_blocking_stream_is_off_when_its_block_ends():
    from topgimbal.sim import BackgroundSimulator

    with BackgroundSimulator("C12", seed=32, listen={"udp": [("127.0.0.1", 0)]}) as bg:  # noqa: SIM117 - bg.url
        with topgimbal.Gimbal(bg.url, model="C12", timeout_s=0.5) as cam:
            with cam.attitude(rate_hz=20) as stream:
                for _att in stream:
                    break
            assert gaa_rates(bg.call(lambda s: list(s.received))) == [20, 0]
            for n, _att in enumerate(cam.attitude(rate_hz=20), 1):  # the short form still works
                if n == 2:
                    break


@pytest.mark.integration
async def test_get_attitude_while_a_stream_runs_is_answered_by_the_next_sample(sim_factory):
    """The stream's frames are the attitude answer's own: they were counted as copies of the last
    answer, so each later query waited for 50 ms without a frame on its key (never, at 50 Hz):
    p50 282 ms, up to 9.6 s. Now a query is sent at once and the next sample answers it."""
    sim = await sim_factory("C12", seed=32)
    async with topgimbal.connect(dict(sim.endpoints)["udp"], model="C12", timeout_s=0.5) as cam:
        samples = 0

        async def consume() -> None:
            nonlocal samples
            async for _att in cam.attitude(rate_hz=50):
                samples += 1

        task = asyncio.ensure_future(consume())
        try:
            await until(lambda: samples >= 5)
            await cam.point(10, -5)
            for _ in range(10):
                att = await cam.get_attitude()
                assert abs(att.yaw_deg - 10) <= 0.5 and abs(att.pitch_deg + 5) <= 0.5
            stats = cam.stats
            assert stats.deferred == 0 and stats.duplicates == 0 and not cam._engine.copies_seen
            assert stats.timeouts == 0 and stats.late_replies == 0
            before = samples
            await until(lambda: samples > before)  # the consumer still gets every sample
        finally:
            task.cancel()
