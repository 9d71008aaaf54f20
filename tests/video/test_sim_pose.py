"""One model of the stabilised gimbal (issue 35.5): pitch and roll are held from the horizon on every
model, so a C12 whose attitude reads level on a tilted vehicle takes photos whose gimbal pose is
level too (it carried the vehicle's tilt: Pitch -2 / Roll +1, Camera:Pitch 88)."""

from __future__ import annotations

import asyncio
import re
from pathlib import Path

import pytest

import topgimbal
from topgimbal.sim import Simulator
from topgimbal.video.media import MediaStore

pytestmark = pytest.mark.loopback


def xmp(path: Path) -> dict[str, float]:
    text = path.read_bytes().decode("latin-1")
    return {k: float(v) for k, v in re.findall(r'([\w-]+:\w+)="([-+0-9.]+)"', text)}


@pytest.mark.parametrize("pitch_deg", [0.0, -30.0])
async def test_a_c12_on_a_tilted_vehicle_photographs_the_pose_it_reports(tmp_path: Path, pitch_deg: float) -> None:
    sim = Simulator("C12")
    await sim.start(udp=[("127.0.0.1", 0)])
    store = MediaStore(sim, tmp_path).start()
    try:
        async with topgimbal.connect(sim.url, model="C12", timeout_s=1, check_model=False) as cam:
            await cam.vehicle_attitude(10.0, 2.0, -1.0)  # nose 2 deg up, rolled 1 deg left
            while sim.device.gimbal.vehicle.pitch != 2.0:
                await asyncio.sleep(0.05)
            reached = await cam.point(0.0, pitch_deg, tolerance_deg=0.3)
            await asyncio.sleep(0.5)  # let the roll axis settle on the horizon too
            att = await cam.get_attitude()
            await cam.photo()
            while not (tmp_path / "IMG_0001.jpg").exists():
                await asyncio.sleep(0.05)
    finally:
        await store.stop()
        await sim.stop()
    assert reached.pitch_deg == pytest.approx(pitch_deg, abs=0.3)
    tags = xmp(tmp_path / "IMG_0001.jpg")
    assert tags["drone-dji:GimbalPitchDegree"] == pytest.approx(att.pitch_deg, abs=0.1)
    assert tags["drone-dji:GimbalRollDegree"] == pytest.approx(att.roll_deg, abs=0.1)
    assert tags["drone-dji:GimbalPitchDegree"] == pytest.approx(pitch_deg, abs=0.3)
    assert tags["drone-dji:GimbalRollDegree"] == pytest.approx(0.0, abs=0.1)
    assert tags["Camera:Pitch"] == pytest.approx(90.0 + pitch_deg, abs=0.3)
    assert tags["drone-dji:FlightPitchDegree"] == pytest.approx(2.0, abs=0.01)  # the tilt is the vehicle's
