"""MAV_CMD_OBLIQUE_SURVEY on the camera component, the camera and its gimbal one component
(issue 42): distance triggers from the vehicle's GLOBAL_POSITION_INT, the roll positions in turn,
one per photo, logged with the roll the camera reported, and in each photo's XMP."""

from __future__ import annotations

import asyncio
import itertools
import math
import re
from pathlib import Path
from typing import Any

import pytest
from pymavlink.dialects.v20 import common as ml

from topgimbal.clock import monotonic
from topgimbal.mavlink.survey import roll_order, roll_positions
from topgimbal.video.media import MediaStore

from .virtual import MemPeer

pytestmark = pytest.mark.virtual

CAMERA = 100
LAT0, LON0 = 47.397742, 8.545594
SPEED_M_S = 10.0
METRES_PER_DEG = math.pi / 180 * 6371008.8
DISTANCE_M = 20.0


def xmp(path: Path) -> dict[str, float]:
    text = path.read_bytes().decode("latin-1")
    return {k: float(v) for k, v in re.findall(r'([\w-]+:\w+)="([-+0-9.]+)"', text)}


async def _fly_north(autopilot: MemPeer, t0: float) -> None:
    i = 0
    while True:
        north_m = SPEED_M_S * (monotonic() - t0)
        lat = LAT0 + north_m / METRES_PER_DEG
        autopilot.send(ml.MAVLink_global_position_int_message(round((monotonic() - t0) * 1000), round(lat * 1e7), round(LON0 * 1e7), 500_000,
                                                              50_000, int(SPEED_M_S * 100), 0, 0, 0))  # fmt: skip
        if i % 10 == 0:
            autopilot.send(ml.MAVLink_heartbeat_message(2, 3, 0, 0, 4, 3))
        i += 1
        await asyncio.sleep(0.1)


def test_roll_positions_spread_evenly_over_the_limits() -> None:
    assert roll_positions(3, 20.0) == [-20.0, 0.0, 20.0]
    assert roll_positions(5, 30.0) == [-30.0, -15.0, 0.0, 15.0, 30.0]
    assert roll_positions(1, 30.0) == [0.0]
    assert roll_order(3) == [0, 1, 2, 1] and roll_order(2) == [0, 1] and roll_order(1) == [0]


async def test_oblique_survey_rolls_per_photo_at_the_distance(vrig_maker: Any, tmp_path: Path) -> None:
    vrig = await vrig_maker("C12", role="device")
    store = MediaStore(vrig.sim, tmp_path).start()
    autopilot = await MemPeer(sysid=1, compid=1).join(vrig.link)
    fly = asyncio.ensure_future(_fly_north(autopilot, monotonic()))
    try:
        await asyncio.sleep(1.0)
        # 20 m apart, 0.5 s at least, 3 roll positions within +-15 deg, pitch -40 deg (the C12: -45 at
        # most). The C12 turns 12.7 deg/s at most: a 15 deg step fits in the 2 s between photos at
        # 10 m/s, a 20 deg one does not (each photo waited 0.15-0.27 s for it: 21.5-22.7 m apart)
        ack = await vrig.peer.ack(CAMERA, ml.MAV_CMD_OBLIQUE_SURVEY, DISTANCE_M, 0, 500, 3, 15, -40)
        assert ack.result == ml.MAV_RESULT_ACCEPTED
        # the first photo once the gimbal is there (pitch -40 and roll -15 from level: about 4 s on a
        # C12), then one every 20 m (2 s): six photos within 20 s
        t0 = monotonic()
        while len(vrig.bridge.survey.shots) < 6 and monotonic() - t0 < 20.0:
            await asyncio.sleep(0.05)
        ack = await vrig.peer.ack(CAMERA, ml.MAV_CMD_OBLIQUE_SURVEY, 0)
        assert ack.result == ml.MAV_RESULT_ACCEPTED
        taken = vrig.sim.camera.photos_taken
        await asyncio.sleep(5.0)
        assert vrig.sim.camera.photos_taken == taken  # stopped
        shots = vrig.bridge.survey.shots
        assert len(shots) == 6 == taken, shots
        assert [s.roll_asked_deg for s in shots] == [-15.0, 0.0, 15.0, 0.0, -15.0, 0.0]  # there and back
        for s in shots:
            assert s.roll_deg is not None and abs(s.roll_deg - s.roll_asked_deg) <= 1.0, s
        gaps = [s.from_last_m for s in shots[1:]]
        assert all(g is not None and abs(g - DISTANCE_M) <= 0.1 * DISTANCE_M for g in gaps), gaps
        # the photos' own positions (CAMERA_IMAGE_CAPTURED) are DISTANCE_M apart too
        records = {m.image_index: m for m in vrig.peer.messages if m.get_type() == "CAMERA_IMAGE_CAPTURED"}
        lats = [records[s.image_index].lat / 1e7 for s in shots]
        spacing = [(b - a) * METRES_PER_DEG for a, b in itertools.pairwise(lats)]
        assert all(abs(d - DISTANCE_M) <= 0.1 * DISTANCE_M for d in spacing), spacing
    finally:
        fly.cancel()
        autopilot.close()
        await store.stop()
    # each photo's XMP carries the roll it was taken at
    files = sorted(tmp_path.glob("IMG_????.jpg"))  # the visible lens (IMG_nnnn_T.jpg: thermal)
    assert len(files) == 6, files
    for f, s in zip(files, shots, strict=True):
        tags = xmp(f)
        assert s.roll_deg is not None
        assert tags["drone-dji:GimbalRollDegree"] == pytest.approx(s.roll_deg, abs=0.5), f.name
        assert tags["drone-dji:GimbalPitchDegree"] == pytest.approx(-40.0, abs=1.0), f.name


async def test_a_roll_beyond_the_gimbal_is_refused(vrig_maker: Any) -> None:
    vrig = await vrig_maker("C12", role="device")
    ack = await vrig.peer.ack(CAMERA, ml.MAV_CMD_OBLIQUE_SURVEY, 20, 0, 0, 3, 120, -40)
    assert ack.result == ml.MAV_RESULT_DENIED
    ack = await vrig.peer.ack(CAMERA, ml.MAV_CMD_OBLIQUE_SURVEY, 20, 0, 0, 3, 20, -60)  # the C12 pitches -45 at most
    assert ack.result == ml.MAV_RESULT_DENIED
    assert not vrig.bridge.survey.running
