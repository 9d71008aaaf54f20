"""The camera's own tracker (sim/tracker.py) driven by the wire commands: it follows a moving
target within the model's rates, coasts through a short occlusion, loses the target after a
long one or out of the picture, and says so in its state."""

from __future__ import annotations

import pytest

from topgimbal.sim.targets import parse_spec
from topgimbal.sim.tracker import TRAITS, project
from topgimbal.video.lens import tracking_requests

from .conftest import DeviceHarness

pytestmark = pytest.mark.virtual


def _start(h: DeviceHarness, bearing: float, elevation: float, box: float = 0.05) -> None:
    """Ask for tracking of a box around a direction, as the bridge and console do (video.lens)."""
    st = h.dev.state
    yaw, pitch, _ = st.gimbal.earth()
    x, y = project(yaw, pitch, bearing, elevation, st.tracking_hfov_deg())  # type: ignore[misc]
    for ident, values in tracking_requests(h.dialect, h.dev.model, x - box, y - box, x + box, y + box):
        h.ask(ident, **values)


def _trc(h: DeviceHarness) -> str:
    (answer,) = h.ask("TRC", read=True)
    return str(h.decode(answer)["state"])


def _error_deg(h: DeviceHarness) -> float:
    st = h.dev.state
    (tv,) = st.target_views(h.dev.now)
    yaw, pitch, _ = st.gimbal.earth()
    return max(abs((tv.bearing_deg - yaw + 180) % 360 - 180), abs(tv.elevation_deg - pitch))


def test_topotek_follows_a_crossing_target_then_loses_it_behind_a_long_occlusion() -> None:
    h = DeviceHarness("SIP")
    h.dev.state.targets = (parse_spec("bearing=8,elevation=-4,speed=10,hide=4-4.5+8-10"),)
    h.ask("TRC", action="start")
    assert _trc(h) == "waiting"
    _start(h, 8, -4)
    assert _trc(h) == "tracking"
    h.advance(3.0)
    assert _error_deg(h) < 0.1  # caught up and following at 10 deg/s
    h.advance(1.4)  # into the 0.5 s occlusion: shorter than the model's coast time
    assert _trc(h) == "tracking"
    h.advance(1.0)
    assert _trc(h) == "tracking" and _error_deg(h) < 0.1
    h.advance(3.2 + TRAITS["topotek"].coast_s + 0.1)  # 8 s + coast: lost
    assert h.dev.state.camera.tracking == "lost"
    assert _trc(h) == "waiting"  # TOPOTEK has no lost code: ready for a new box (docs/errata.md)
    yaw = h.dev.state.gimbal.earth()[0]
    h.advance(1.0)
    assert h.dev.state.gimbal.earth()[0] == pytest.approx(yaw, abs=1.0)  # stopped following
    h.ask("TRC", action="stop")
    assert _trc(h) == "stopped"


def test_a_target_faster_than_the_gimbal_leaves_the_picture_and_is_lost() -> None:
    h = DeviceHarness("SIP")
    fast = h.dev.model.max_rate_deg_s * 1.5
    h.dev.state.targets = (parse_spec(f"bearing=0,elevation=0,speed={fast:g}"),)
    _start(h, 0, 0)
    h.advance(0.1)
    assert h.dev.state.camera.tracking == "tracking"
    h.advance(30.0)
    assert h.dev.state.camera.tracking == "lost"


def test_skydroid_got_tracks_the_target_at_the_point_and_sum_stops() -> None:
    h = DeviceHarness("C12")
    h.dev.state.targets = (parse_spec("name=a,bearing=-6,elevation=3,speed=5,heading=90"),)
    _start(h, -6, 3)
    assert h.dev.state.tracker is not None and h.dev.state.tracker.target == "a"
    h.advance(2.0)
    assert h.dev.state.camera.tracking == "tracking" and _error_deg(h) < 0.1
    h.ask("SUM", action="confirm")
    assert h.dev.state.camera.tracking == "tracking"
    h.ask("SUM", action="stop")
    assert h.dev.state.camera.tracking == "stopped"


def test_a_box_over_no_target_holds_the_patch_of_scene() -> None:
    h = DeviceHarness("SIP")
    h.dev.state.targets = (parse_spec("bearing=20,elevation=0"),)
    _start(h, 5, -2)
    assert h.dev.state.tracker is not None and h.dev.state.tracker.target is None
    h.advance(3.0)
    yaw, pitch, _ = h.dev.state.gimbal.earth()
    assert (yaw, pitch) == pytest.approx((5, -2), abs=0.05) and _trc(h) == "tracking"
