"""The follow loop's integral (mavlink/pointing.py): it grows with the error over time, up to its
bound, only on small errors, never past the motors' limit, and a long gap counts as the longest
step. (Its effect on a turn: tests/mavlink/test_turning.py, a reported rate 13 % high.)"""

from __future__ import annotations

from types import SimpleNamespace
from typing import Any

import pytest

from topgimbal.mavlink import pointing
from topgimbal.mavlink.pointing import (
    FOLLOW_INTEGRAL_BAND_DEG,
    FOLLOW_INTEGRAL_MAX_DEG_S,
    FOLLOW_INTEGRAL_MAX_DT_S,
    FOLLOW_INTEGRAL_PER_S2,
    Pointer,
)

pytestmark = pytest.mark.virtual

TOP_DEG_S = 12.7  # the C12's motors


@pytest.fixture
def clock(monkeypatch: pytest.MonkeyPatch) -> list[float]:
    now = [100.0]
    monkeypatch.setattr(pointing, "monotonic", lambda: now[0])
    return now


def pointer() -> Pointer:
    cam: Any = SimpleNamespace(profile=SimpleNamespace(model=SimpleNamespace(max_rate_deg_s=TOP_DEG_S)))
    return Pointer(cam, vehicles=SimpleNamespace())  # type: ignore[arg-type]


def run(p: Pointer, clock: list[float], error_deg: float, fed_forward_deg_s: float, seconds: float, dt: float) -> float:
    out = 0.0
    for _ in range(round(seconds / dt)):
        clock[0] += dt
        out = p._grow_integral(error_deg, fed_forward_deg_s)
    return out


def test_it_grows_with_the_error_over_time_up_to_its_bound(clock: list[float]) -> None:
    p = pointer()
    assert p._grow_integral(0.3, -6.0) == 0.0  # the first call starts the clock: no time has passed
    got = run(p, clock, 0.3, -6.0, 1.0, 0.02)
    assert got == pytest.approx(FOLLOW_INTEGRAL_PER_S2 * 0.3 * 1.0)
    assert run(p, clock, 0.3, -6.0, 30.0, 0.02) == FOLLOW_INTEGRAL_MAX_DEG_S
    assert run(p, clock, -0.3, -6.0, 60.0, 0.02) == -FOLLOW_INTEGRAL_MAX_DEG_S  # both ways


def test_a_large_error_is_left_to_the_proportional_term(clock: list[float]) -> None:
    p = pointer()
    p._grow_integral(0.0, -6.0)
    assert run(p, clock, FOLLOW_INTEGRAL_BAND_DEG + 0.1, -6.0, 2.0, 0.02) == 0.0  # a catch-up
    assert run(p, clock, FOLLOW_INTEGRAL_BAND_DEG - 0.1, -6.0, 0.1, 0.02) > 0.0


def test_it_does_not_wind_up_against_the_motors_limit(clock: list[float]) -> None:
    p = pointer()
    p._grow_integral(0.0, -12.6)
    # -12.6 fed forward and 3 x -0.3: past the motors' 12.7 deg/s, so the integral stays put
    assert run(p, clock, -0.3, -12.6, 2.0, 0.02) == 0.0
    assert run(p, clock, 0.3, -12.6, 0.5, 0.02) > 0.0  # back from the limit: it grows again


def test_a_long_gap_counts_as_the_longest_step(clock: list[float]) -> None:
    p = pointer()
    p._grow_integral(0.2, -6.0)
    clock[0] += 5.0  # set-points stopped for 5 s
    assert p._grow_integral(0.2, -6.0) == pytest.approx(FOLLOW_INTEGRAL_PER_S2 * 0.2 * FOLLOW_INTEGRAL_MAX_DT_S)
