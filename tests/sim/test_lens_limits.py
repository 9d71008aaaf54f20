"""The simulated camera's lens limits are its model profile's (read, not copied)."""

from __future__ import annotations

import pytest

from topgimbal.protocol import all_models, get_model
from topgimbal.sim.device import Device

pytestmark = pytest.mark.virtual


@pytest.mark.parametrize("name", all_models())
def test_magnification_stops_at_the_profiles_optical_zoom(name: str) -> None:
    _, profile = get_model(name)
    cam = Device(name).camera
    cam.set_magnification(1000.0)
    assert cam.optical_zoom_x == round(max(1.0, profile.optical_zoom_max), 1)
    cam.set_magnification(0.1)
    assert cam.optical_zoom_x == 1.0


@pytest.mark.parametrize("name", all_models())
def test_digital_zoom_motor_stops_at_the_profiles_limit(name: str) -> None:
    cam = Device(name).camera
    cam.digital_zoom_dir = 1
    cam.advance(1000.0)
    assert cam.digital_zoom_x == get_model(name)[1].digital_zoom_max
    assert cam.digital_zoom_dir == 0
