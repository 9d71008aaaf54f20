"""Gimbal physics on a fake clock: rate and acceleration limits, ranges, frames, motors."""

from __future__ import annotations

import math

import pytest

from topgimbal.protocol import get_model
from topgimbal.sim.physics import Gimbal, GimbalPhysics

pytestmark = pytest.mark.virtual


def gimbal_for(model: str) -> Gimbal:
    _, m = get_model(model)
    return Gimbal.for_limits(m.yaw_range_deg, m.pitch_range_deg, m.roll_range_deg, m.max_rate_deg_s, m.max_accel_deg_s2)


def min_time(distance: float, vmax: float, accel: float) -> float:
    """Fastest trapezoid (or triangle) move over `distance`."""
    if distance * accel <= vmax * vmax:
        return 2 * math.sqrt(distance / accel)
    return distance / vmax + vmax / accel


@pytest.mark.parametrize(
    ("model", "axis", "target"), [("C12", "yaw", 60.0), ("SIP", "yaw", -140.0), ("SIP", "pitch", 80.0)]
)
def test_angle_reached_within_rate_limited_time_without_overshoot(model: str, axis: str, target: float) -> None:
    g = gimbal_for(model)
    ax = g.axis(axis)
    vmax, accel = ax.limits.max_rate, ax.limits.max_accel
    g.angle(axis, target)
    bound = min_time(abs(target), vmax, accel)
    t, dt, peak = 0.0, 0.01, 0.0
    # Not there noticeably before the physical minimum (the limits are enforced)...
    g.advance(bound * 0.9)
    t += bound * 0.9
    assert abs(ax.pos) < abs(target)
    # ...and there within the time the limits allow (plus one step of slack).
    while t < bound + 0.05:
        g.advance(dt)
        t += dt
        peak = max(peak, abs(ax.pos))
        assert abs(ax.vel) <= vmax + 1e-9
    assert ax.pos == pytest.approx(target, abs=1e-6)
    assert peak <= abs(target) + 1e-9  # never overshoots


def test_speed_mode_stops_at_range_end() -> None:
    g = gimbal_for("C12")
    g.rate("yaw", 12.7)
    g.advance(20.0)  # 12.7 deg/s for 20 s would be 254 deg
    assert g.yaw_deg == 90.0
    assert g.yaw_axis.vel == 0.0


def test_commanded_angle_beyond_range_is_clamped() -> None:
    g = gimbal_for("SIP")
    g.angle("yaw", 170.0)
    g.advance(10.0)
    assert g.yaw_deg == 150.0


def test_acceleration_limit_from_rest() -> None:
    g = gimbal_for("SIP")
    g.rate("pitch", 99.0)
    g.advance(0.1)
    a = g.pitch_axis.limits.max_accel
    assert g.pitch_axis.vel == pytest.approx(a * 0.1, rel=1e-6)
    assert g.pitch_deg == pytest.approx(0.5 * a * 0.01, rel=0.05)


def test_slicing_does_not_change_the_result() -> None:
    a, b = gimbal_for("SIP"), gimbal_for("SIP")
    for gg in (a, b):
        gg.angle("yaw", 100.0, speed=30.0)
    a.advance(1.0)
    for _ in range(100):
        b.advance(0.01)
    assert a.yaw_deg == pytest.approx(b.yaw_deg, abs=1e-6)


def test_stop_decelerates_then_holds() -> None:
    g = gimbal_for("SIP")
    g.rate("yaw", 50.0)
    g.advance(1.0)
    g.stop()
    g.advance(1.0)
    held = g.yaw_deg
    g.advance(1.0)
    assert g.yaw_deg == held
    assert g.yaw_axis.mode == "angle"


def test_earth_frame_target_compensates_vehicle_attitude() -> None:
    g = gimbal_for("SIP")
    g.vehicle.pitch = 10.0
    g.angle("pitch", -30.0, frame="earth")
    g.advance(5.0)
    assert g.pitch_deg == pytest.approx(-40.0)  # body angle
    assert g.earth()[1] == pytest.approx(-30.0)


def test_lock_mode_holds_heading_when_vehicle_turns_follow_does_not() -> None:
    g = gimbal_for("SIP")
    g.set_mode("lock")
    g.vehicle.yaw = 20.0
    g.advance(5.0)
    assert g.earth()[0] == pytest.approx(0.0, abs=1e-6)
    assert g.yaw_deg == pytest.approx(-20.0)
    g.set_mode("follow")
    g.vehicle.yaw = 40.0
    g.advance(5.0)
    assert g.yaw_deg == pytest.approx(-20.0)
    assert g.earth()[0] == pytest.approx(20.0)


def test_motors_off_ignores_motion() -> None:
    g = gimbal_for("C12")
    g.set_motors(False)
    g.angle("yaw", 45.0)
    g.rate("pitch", 10.0)
    g.advance(5.0)
    assert (g.yaw_deg, g.pitch_deg) == (0.0, 0.0)
    g.set_motors(True)
    g.angle("yaw", 45.0)
    g.advance(10.0)
    assert g.yaw_deg == pytest.approx(45.0)


def test_idle_time_costs_no_integration_steps(monkeypatch: pytest.MonkeyPatch) -> None:
    """A gimbal at rest on its targets is not walked through an idle hour in 2 ms slices (the first
    request after a long pause used to do that: 186 ms of work per idle minute)."""
    from topgimbal.sim import physics

    g = gimbal_for("C12")
    g.angle("yaw", 10.0, None, "body")
    g.advance(5.0)  # reaches the target
    assert math.isclose(g.yaw_deg, 10.0, abs_tol=1e-6)
    checks = 0
    real = physics.Axis.body_target

    def counting(self, *a, **kw):  # type: ignore[no-untyped-def]
        nonlocal checks
        checks += 1
        return real(self, *a, **kw)

    monkeypatch.setattr(physics.Axis, "body_target", counting)
    g.advance(3600.0)
    assert checks <= 3 and math.isclose(g.yaw_deg, 10.0, abs_tol=1e-6)
    g.angle("yaw", 20.0, None, "body")
    g.advance(1.0)
    assert checks > 3 and g.yaw_deg > 10.0  # motion is still integrated


def test_the_physics_class_has_its_own_name_and_the_old_one_still_works() -> None:
    import topgimbal

    assert Gimbal is GimbalPhysics and GimbalPhysics is not topgimbal.Gimbal
    assert GimbalPhysics.__name__ == "GimbalPhysics"
