"""`Simulator.sync()`: the gimbal's attributes hold the device's last step until the physics is
brought up to now (tests scoring where a turning camera points read it after a sync)."""

from __future__ import annotations

import pytest

from topgimbal.sim import FakeClock, Simulator

pytestmark = pytest.mark.virtual


def test_the_gimbal_reads_its_last_step_until_synced() -> None:
    clock = FakeClock()
    sim = Simulator("C12", clock=clock)
    sim.advance(0.1)  # a first step: the physics is at 0.1 s
    sim.gimbal.rate("yaw", -6.0)
    start = sim.gimbal.yaw_deg
    clock.set(clock.now() + 0.5)  # time passes with no step (no stream, no command)
    assert sim.gimbal.yaw_deg == start  # the attribute is the last step's
    sim.sync()
    assert sim.gimbal.yaw_deg == pytest.approx(start - 3.0, abs=0.3)  # 0.5 s at -6 deg/s (motors accelerate)
    moved = sim.gimbal.yaw_deg
    sim.sync()  # nothing more passed: nothing moves, and it never steps back
    assert sim.gimbal.yaw_deg == moved
