"""Link loss is visible and heals by itself: a quiet device (in-memory port) or a closed TCP
connection turns `connected` False, ends streams with LinkLostError, fails pending requests at once,
reports both transitions, and everything works again when frames come back. No timing asserts:
only the order of events (each wait is bounded)."""

from __future__ import annotations

import asyncio

import pytest

import topgimbal
import waiting
from topgimbal.errors import LinkLostError, TransportError

pytestmark = pytest.mark.virtual


async def until(predicate, limit_s: float = 10.0) -> None:
    await waiting.until("the link's state", predicate, bound_s=limit_s, every_s=0.01)  # tests/waiting.py


async def test_a_quiet_device_ends_streams_fails_requests_and_comes_back(fake):
    url = fake.start_memory()
    fake.answers["REC"] = {"state": "stopped"}
    events: list[tuple[bool, str]] = []
    async with topgimbal.connect(url, model="C12", timeout_s=0.2, link_timeout_s=0.5) as cam:
        cam.on_link_change(lambda up, reason: events.append((up, reason)))
        samples = 0
        with pytest.raises(LinkLostError) as lost:
            async for _att in cam.attitude(rate_hz=50):
                samples += 1
                if samples == 3:
                    fake.muted = True  # the device is gone: nothing comes any more
        assert samples >= 3 and "link lost" in str(lost.value) and "nothing heard" in str(lost.value)
        assert not cam.connected and cam.stats.connected is False and cam.stats.link_losses == 1
        assert events == [(False, events[0][1])] and "nothing heard" in events[0][1]
        assert cam.link_state["up"] is False and cam.link_state["silent_s"] > 0
        fake.muted = False  # back: a frame brings the link up by itself
        assert await cam.recording() is False
        assert cam.connected and [e[0] for e in events] == [False, True]


async def test_pending_requests_fail_at_once_when_the_link_goes_down(fake):
    url = fake.start_memory()
    async with topgimbal.connect(url, model="C12", timeout_s=30, link_timeout_s=0.3) as cam:
        await cam.attitude_stream(20)  # frames flow; a stream is expected to go on
        fake.muted = True
        pending = asyncio.ensure_future(cam.recording())  # would wait 30 s per attempt
        with pytest.raises(LinkLostError):
            await asyncio.wait_for(pending, 10)
        fake.muted = False
        await until(lambda: cam.connected)  # pings while down notice the device is back
        assert await cam.version()


@pytest.mark.loopback
async def test_a_closed_tcp_connection_is_lost_at_once_and_reconnects(fake):
    url = await fake.start_tcp()
    fake.handler = lambda f: None  # never answers
    events: list[bool] = []
    async with topgimbal.connect(url, model="C12", timeout_s=30, reconnect_s=0.05) as cam:
        cam.on_link_change(lambda up, reason: events.append(up))
        tasks = [asyncio.ensure_future(c) for c in (cam.recording(), cam.sd_card(), cam.get_attitude())]
        await until(lambda: len(fake.received) >= 3)
        for t in fake.tcp_peers:
            t.close()
        results = await asyncio.gather(*tasks, return_exceptions=True)
        assert all(isinstance(r, LinkLostError) for r in results), results
        assert events[0] is False
        fake.handler = fake.default
        fake.answers["REC"] = {"state": "stopped"}
        await until(lambda: events == [False, True])
        assert cam.connected and await cam.recording() is False


async def test_a_memory_port_closing_is_a_lost_link(fake):
    url = fake.start_memory()
    fake.answers["REC"] = {"state": "stopped"}
    async with topgimbal.connect(url, model="C12", timeout_s=0.5, reconnect_s=None) as cam:
        assert await cam.recording() is False
        fake.port.disconnect()
        assert not cam.connected
        with pytest.raises(TransportError):
            await cam.recording()
