"""The companion loop's pure parts: the attitude history, the PI law against a delayed plant, and
the vision on the simulator's pictures."""

from __future__ import annotations

import math

import numpy as np
import pytest

from topgimbal.sim import FakeClock
from topgimbal.sim.device import Device
from topgimbal.sim.targets import parse_spec
from topgimbal.sim.truth import truth_record
from topgimbal.track.control import AngleController, AttitudeHistory, Gains, PixelPGains, pixel_p_rates
from topgimbal.track.loop import TrackConfig, capture_time
from topgimbal.track.vision import TrackerError, VisualTracker
from topgimbal.video.render import Renderer
from topgimbal.video.snapshot import capture

pytestmark = pytest.mark.loopback


def test_history_interpolates_wraps_and_extrapolates_a_little() -> None:
    h = AttitudeHistory()
    assert h.at(1.0) is None
    h.add(0.0, 170.0, 0.0)
    h.add(1.0, -170.0, 10.0)  # crossed +-180: 20 degrees to the right, not 340 to the left
    h.add(0.5, 0.0, 0.0)  # out of order: ignored
    assert h.at(0.5) == pytest.approx((180.0, 5.0))
    assert h.at(-1.0) == (170.0, 0.0)
    assert h.at(1.1) == pytest.approx((-168.0, 11.0))
    assert h.at(5.0) == pytest.approx((-166.0, 12.0))  # at most 0.2 s beyond the newest


def _run(law: str, latency_s: float, compensate: bool, seconds: float = 8.0, settle_s: float = 0.0) -> float:
    """A gimbal that follows its rate command exactly, a target crossing at 10 deg/s from 2 degrees
    off the axis, pictures every 40 ms that arrive `latency_s` late; RMS angle error after
    `settle_s`."""
    dt, frame = 0.01, 0.04
    ctl = AngleController(Gains(max_rate_deg_s=60.0))
    hist = AttitudeHistory()
    yaw, rate = 0.0, (0.0, 0.0)
    pending: list[tuple[float, float, float]] = []  # (arrives, taken, target offset seen)
    errors = []
    t = 0.0
    while t < seconds:
        target = 2.0 + 10.0 * t
        hist.add(t, yaw, 0.0)
        if round(t / frame, 6) % 1 == 0:
            pending.append((t + latency_s, t, target - yaw))
        while pending and pending[0][0] <= t + 1e-9:
            _, taken, seen = pending.pop(0)
            stamp = taken if compensate else t
            att = hist.at(stamp)
            assert att is not None
            ctl.observe(stamp, att[0] + seen, 0.0)
            if law == "pixel-p":
                rate = pixel_p_rates((seen, 0.0), PixelPGains(kp_per_s=3.0, max_rate_deg_s=60.0))
        if law == "pi":
            rate = ctl.command(t, yaw, 0.0)
        yaw += rate[0] * dt
        t += dt
        if t > settle_s:
            errors.append(2.0 + 10.0 * t - yaw)
    return math.sqrt(sum(e * e for e in errors) / len(errors))


def test_the_pi_law_with_latency_compensation_beats_a_p_only_pixel_loop() -> None:
    pi = _run("pi", 0.15, compensate=True, settle_s=2.0)
    uncompensated = _run("pi", 0.15, compensate=False, settle_s=2.0)
    pixel_p = _run("pixel-p", 0.15, compensate=True, settle_s=2.0)
    assert pi < 0.1  # the target at 10 deg/s is held on the axis
    assert pixel_p > 3.0  # P only lags by v / kp = 3.3 degrees
    assert uncompensated > pi * 2  # a late picture taken as new: the gimbal's own motion reads as the target's


def test_vision_finds_the_target_snaps_to_it_and_notices_when_it_is_hidden() -> None:
    dev = Device("C10", clock=FakeClock())
    dev.state.targets = (parse_spec("bearing=3,elevation=4,size=2,contrast=0.9,hide=1-2"),)
    r = Renderer("visible", 640, 360, 60.0)
    tr = truth_record(dev)["targets"][0]
    tx, ty = tr["x"] * 640, tr["y"] * 360
    first = np.asarray(r.render(capture(dev, wall_s=0.0)))
    vt = VisualTracker("kcf")
    # drawn off-centre: snapped onto the target (within 2 px: Pillow rounds the disc to pixels)
    vt.start(first, (tx - 35, ty - 20, 50, 50))
    assert vt.centre is not None and math.hypot(vt.centre[0] - tx, vt.centre[1] - ty) < 2.0
    assert vt.update(first) is not None and vt.score > 0.9
    dev.clock.advance(1.5)  # type: ignore[attr-defined]
    hidden = np.asarray(r.render(capture(dev, wall_s=0.0)))
    assert vt.update(hidden) is None and not vt.locked
    assert vt.reacquire(hidden, (tx, ty)) is None
    dev.clock.advance(1.0)  # type: ignore[attr-defined]
    back = np.asarray(r.render(capture(dev, wall_s=0.0)))
    assert vt.reacquire(back, (tx + 30, ty)) is not None and vt.locked
    assert vt.centre is not None and math.hypot(vt.centre[0] - tx, vt.centre[1] - ty) < 2.0


def test_bad_settings_are_named() -> None:
    with pytest.raises(TrackerError, match="tracker must be one of"):
        VisualTracker("boosting")
    with pytest.raises(TrackerError, match="box must be"):
        TrackConfig(box=(0.9, 0.9, 0.2, 0.2))
    with pytest.raises(TrackerError, match="law must be"):
        TrackConfig(law="pid")
    assert capture_time(10.0, 1000.0, 999_850, 0.5) == pytest.approx(9.85)  # from the stamp
    assert capture_time(10.0, 1000.0, None, 0.5) == 9.5  # from the configured latency
