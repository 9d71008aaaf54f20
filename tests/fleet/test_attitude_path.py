"""The fleet server's attitude path, piece by piece: the hand-written JSON is the JSON a subscriber
parses, and the client's attitude tap (what the server publishes from) sees every sample and
survives a tap that raises."""

from __future__ import annotations

import itertools
import json
import logging
import math

import pytest

import topgimbal
from topgimbal.client.state import GimbalAttitude
from topgimbal.fleet.batch import batch_head, named
from topgimbal.fleet.camera import attitude_json

from .conftest import eventually

pytestmark = pytest.mark.virtual


@pytest.mark.parametrize(
    ("yaw", "pitch", "roll"), [(0.0, 0.0, 0.0), (-179.99, 89.5, 1e-7), (12.345678901234, -0.1, 3e21)]
)
def test_the_attitude_json_is_json_with_the_same_values(yaw: float, pitch: float, roll: float) -> None:
    att = GimbalAttitude(yaw, pitch, roll, t=5.0, wall=1764201234.123456)
    d = json.loads(attitude_json(att, 42))
    assert d == {"yaw_deg": yaw, "pitch_deg": pitch, "roll_deg": roll, "t": 1764201234.123456, "seq": 42}


def test_a_value_that_is_not_finite_is_null_not_invalid_json() -> None:
    d = json.loads(attitude_json(GimbalAttitude(math.nan, math.inf, 1.0, wall=1.0), 1))
    assert d["yaw_deg"] is None and d["pitch_deg"] is None and d["roll_deg"] == 1.0


@pytest.mark.parametrize(
    "att",
    [GimbalAttitude(12.5, -30.25, 0.0, t=5.0, wall=1764201234.123456), GimbalAttitude(math.nan, 1.0, -math.inf)],
)
def test_a_batch_sample_made_in_one_step_is_the_named_sample(att: GimbalAttitude) -> None:
    """The batch key's sample is made in one step per sample (the camera's name opens it): the same
    text as the camera's own sample with the name put first, finite or not."""
    one_step = attitude_json(att, 7, batch_head("left-1"))
    assert one_step == named("left-1", attitude_json(att, 7))
    d = json.loads(one_step)
    assert list(d)[:2] == ["name", "yaw_deg"] and d["name"] == "left-1" and d["seq"] == 7


@pytest.mark.loopback
async def test_a_tap_sees_every_sample_and_a_failing_tap_hurts_nothing(sims, caplog) -> None:
    (sim,) = await sims(1)
    async with topgimbal.connect(sim.url, model="C12") as cam:
        seen: list[GimbalAttitude] = []

        def broken(att: GimbalAttitude) -> None:
            raise ValueError("a bug in someone's tap")

        remove_broken = cam.streams.tap(broken)
        remove = cam.streams.tap(seen.append)
        with caplog.at_level(logging.ERROR, logger="topgimbal.client"):
            await cam.attitude_stream(50)
            await eventually(lambda: len(seen) >= 20, what="20 samples through the tap")
        assert "attitude tap" in caplog.text  # logged, and the next tap still ran
        assert all(b.t > a.t for a, b in itertools.pairwise(seen))  # each sample once, in order
        remove_broken()
        remove()
        n = len(seen)
        await cam.get_attitude()  # an answer is a sample too, but no tap is left to see it
        assert len(seen) == n


@pytest.mark.loopback
async def test_the_camera_key_is_put_only_while_someone_subscribes_to_it(sims, zport) -> None:
    """Zenoh's matching status drives the per-camera put (a subscriber on another session, through
    the network): none while nobody listens, every sample once someone does, none again after."""
    import asyncio

    from topgimbal.fleet.camera import ServedCamera
    from topgimbal.fleet.specs import CameraSpec

    from .conftest import raw_session

    (sim,) = await sims(1)
    server = await asyncio.to_thread(raw_session, zport, "peer", [f"tcp/127.0.0.1:{zport}"])
    other = await asyncio.to_thread(raw_session, zport)
    cam = ServedCamera(CameraSpec("north", sim.url, "C12"), server, rate_hz=50)
    puts: list[str] = []
    try:
        await cam.start()
        cam._att = _CountingPublisher(cam._att, puts)  # closing undeclares the real one (cam._decls)
        await eventually(lambda: cam.published >= 10, what="10 samples taken")
        assert not cam.att_subscribed and puts == []  # nobody listens: nothing put
        heard: list[dict[str, float]] = []
        sub = other.declare_subscriber(
            "topgimbal/north/attitude", lambda s: heard.append(json.loads(s.payload.to_string()))
        )
        await eventually(lambda: len(heard) >= 10, what="10 samples on the camera's key")
        assert cam.att_subscribed
        seqs = [int(d["seq"]) for d in heard]
        assert seqs == list(range(seqs[0], seqs[0] + len(seqs)))  # from then on, every sample
        sub.undeclare()
        await eventually(lambda: not cam.att_subscribed, what="the matching status back to none")
        n = len(puts)
        published = cam.published
        await eventually(lambda: cam.published >= published + 10, what="10 more samples taken")
        assert len(puts) <= n + 1  # at most one put raced the status change
    finally:
        await cam.close()
        other.close()
        server.close()


@pytest.mark.loopback
async def test_serving_cameras_starts_no_thread_per_camera(sims, zport) -> None:
    """Zenoh's callbacks (the call and info queryables, matching status, transport events) run
    where Zenoh calls them: zenoh-python's default gives each a Python thread, three per camera,
    which once capped a process at 256 cameras. A call still gets its answer."""
    import asyncio
    import threading

    from topgimbal.fleet.camera import ServedCamera
    from topgimbal.fleet.specs import CameraSpec

    from .conftest import raw_call, raw_session

    made = await sims(12)
    server = await asyncio.to_thread(raw_session, zport, "peer", [f"tcp/127.0.0.1:{zport}"])
    other = await asyncio.to_thread(raw_session, zport)
    before = threading.active_count()
    cams = [ServedCamera(CameraSpec(f"c{i}", s.url, "C12"), server, rate_hz=10) for i, s in enumerate(made)]
    try:
        for cam in cams:
            await cam.start()
        assert threading.active_count() - before < len(cams)  # was 3 per camera: 36
        info = await asyncio.to_thread(raw_call, other, "topgimbal/c7/info", None)
        assert info and info[0]["name"] == "c7"
        got = await asyncio.to_thread(raw_call, other, "topgimbal/c3/call/version", "{}")
        assert got and "result" in got[0], got
    finally:
        for cam in cams:
            await cam.close()
        other.close()
        server.close()


class _CountingPublisher:
    """A Zenoh publisher whose puts are also recorded (the rest goes to the real one)."""

    def __init__(self, inner: object, puts: list[str]) -> None:
        self.inner, self.puts = inner, puts

    def put(self, payload: str) -> None:
        self.puts.append(payload)
        self.inner.put(payload)  # type: ignore[attr-defined]

    def __getattr__(self, name: str) -> object:
        return getattr(self.inner, name)
