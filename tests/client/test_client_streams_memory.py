"""Attitude streams stop deterministically when their consumer leaves (issue 17, item 1), against a
fake device on `memory://`: the virtual tier, on looptime (a loaded machine's stall cannot declare
the link lost and resend a stream request, as it did once in real time). The tests that need a
simulator on loopback stay in test_client_streams.py."""

from __future__ import annotations

import asyncio
import gc
import itertools

import pytest

import topgimbal
from topgimbal.errors import RequestTimeoutError

from .test_client_link import until

pytestmark = pytest.mark.virtual


def gaa_rates(frames) -> list[int]:
    return [int(f.data, 16) for f in frames if f.ident == "GAA" and f.rw == "w"]


async def test_a_context_managed_stream_is_off_when_the_block_ends(fake):
    url = fake.start_memory()
    async with topgimbal.connect(url, model="C12", timeout_s=0.5) as cam:
        async with cam.attitude(rate_hz=20) as stream:
            async for _att in stream:
                break
        # the stop was sent and acknowledged before the block ended: not left to the GC
        assert gaa_rates(fake.received) == [20, 0] and cam.streams.device_rate is None


async def test_a_dropped_stream_is_released_and_a_second_consumer_keeps_it(fake):
    url = fake.start_memory()
    async with topgimbal.connect(url, model="C12", timeout_s=0.5) as cam:
        async with cam.attitude(rate_hz=10) as keeper:
            async for _att in cam.attitude(rate_hz=40):  # raises the rate while it runs
                break
            gc.collect()
            await until(lambda: gaa_rates(fake.received)[-1] == 10)  # back to what the keeper needs
            assert await keeper.__anext__()
        assert gaa_rates(fake.received) == [10, 40, 10, 0]


async def test_an_abandoned_consumer_is_released_without_the_garbage_collector(fake):
    url = fake.start_memory()
    async with topgimbal.connect(url, model="C12", timeout_s=0.5) as cam:
        stream = cam.attitude(rate_hz=50, abandon_after_s=0.1)
        await stream.__anext__()  # started; then the consumer stops asking (but is still referenced)
        await until(lambda: gaa_rates(fake.received)[-1:] == [0])
        assert await stream.__anext__()  # coming back starts it again
        assert gaa_rates(fake.received)[-1] == 50
        await stream.aclose()


async def test_point_falls_back_to_polling_and_says_where_the_gimbal_was(fake):
    url = fake.start_memory()
    fake.attitude = (1.0, 2.0, 0.0)  # a gimbal that never moves
    async with topgimbal.connect(url, model="C12", timeout_s=0.2) as cam:
        await cam.attitude_stream(20)
        fake._set_stream(0)  # ... and whose stream stopped on its own: no sample will come
        with pytest.raises(RequestTimeoutError) as err:
            await cam.point(5, -5, timeout_s=1.0)
        text = str(err.value)
        assert "did not reach yaw 5, pitch -5" in text and "last attitude seen: yaw 1.00, pitch 2.00" in text
        polls = [f for f in fake.received if f.ident == "GAC" and f.rw == "r"]
        assert len(polls) >= 2  # it asked, since the stream said nothing


async def test_stream_samples_are_decimated_to_the_asked_rate(fake):
    url = fake.start_memory()
    async with topgimbal.connect(url, model="C12", timeout_s=0.5) as cam:
        await cam.attitude_stream(50)
        ts = []
        async with cam.attitude(rate_hz=10) as stream:
            async for att in stream:
                ts.append(att.t)
                if len(ts) == 4:
                    break
        gaps = [b - a for a, b in itertools.pairwise(ts)]
        assert all(g >= 0.09 * 0.99 for g in gaps), gaps  # never faster than asked (10 % slack)
        await asyncio.sleep(0)


async def test_two_tasks_reading_one_stream_both_get_samples(fake):
    """The second reader's wait used to replace the first's, which then waited forever."""
    url = fake.start_memory()
    async with topgimbal.connect(url, model="C12", timeout_s=0.5) as cam:
        stream = cam.attitude(rate_hz=50)

        async def read(n: int) -> int:
            got = 0
            async for _att in stream:
                got += 1
                if got == n:
                    return got
            return got

        assert await asyncio.wait_for(asyncio.gather(read(5), read(5)), 30) == [5, 5]
        # a reader cancelled mid-wait does not cancel the other
        other = asyncio.ensure_future(read(3))
        cancelled = asyncio.ensure_future(read(10**6))
        await until(lambda: stream._waiter is not None)
        cancelled.cancel()
        assert await asyncio.wait_for(other, 30) == 3
        await stream.aclose()


async def test_closing_a_stream_ends_the_task_waiting_on_it(fake):
    """aclose() from one task while another waits in `async for`: the waiting one ends (it used
    to wait forever, the stream being released and fed no more)."""
    url = fake.start_memory()
    async with topgimbal.connect(url, model="C12", timeout_s=0.5) as cam:
        stream = await cam.attitude(rate_hz=1).start()
        fake._set_stream(0)  # the device sends nothing more: the reader waits
        samples: list[object] = []

        async def read() -> None:
            async for att in stream:
                samples.append(att)

        reader = asyncio.ensure_future(read())
        await until(lambda: stream._waiter is not None)
        await stream.aclose()
        await asyncio.wait_for(reader, 30)
        assert reader.done() and reader.exception() is None
