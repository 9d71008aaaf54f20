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
