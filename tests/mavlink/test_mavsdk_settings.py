"""MAVSDK 4.x's camera settings API (it downloads the definition itself, reads and writes the
settings over PARAM_EXT) against bridge + simulator: the options are the catalog's, a palette set
changes the simulator's palette, and a read gives the camera's value."""

from __future__ import annotations

import asyncio
from typing import Any

import pytest
from mavsdk.asyncio import ComponentType, Configuration
from mavsdk.asyncio.plugins.camera import CameraAsync
from mavsdk.plugins.camera.camera import Option, Setting

from topgimbal.camdef.definition import settings_for

from .conftest import Rig, eventually, keep, mavsdk_session
from .test_mavsdk import _until

# MAVSDK can hang its caller: each test in a child of its own (conftest.mavsdk_session)
pytestmark = [pytest.mark.external, pytest.mark.integration, pytest.mark.cage(240)]
THERMAL = 101


async def _options(camera: CameraAsync) -> Any:
    """MAVSDK answers UNAVAILABLE until it has the definition and every value: ask until it has."""
    last: Exception | None = None
    for _ in range(60):
        try:
            return await camera.get_possible_setting_options(THERMAL)
        except Exception as exc:  # mavsdk's CameraError: UNAVAILABLE while it loads
            last = exc
        await asyncio.sleep(0.5)
    raise AssertionError(f"MAVSDK never offered the thermal camera's settings ({last})")


@pytest.mark.parametrize("model", ["SIP", "C12"])
async def test_mavsdk_camera_settings(rig_factory: Any, model: str) -> None:
    rig: Rig = await rig_factory(model, timeout_s=1.0, retries=2)
    cfg = Configuration.create_with_component_type(ComponentType.GROUND_STATION)
    async with mavsdk_session(cfg) as mavsdk:
        await mavsdk.add_any_connection(f"udpout://127.0.0.1:{rig.bridge.addresses[0][1]}")  # type: ignore[index]
        await eventually(lambda: mavsdk._mavsdk.system_count() > 0, 15, "MAVSDK sees the system")
        camera = CameraAsync((await mavsdk.get_systems())[0])
        keep(camera)
        found = await _until(camera.subscribe_camera_list(), lambda c: len(c.cameras) >= 2, 30)
        assert found is not None, "the two cameras were not discovered"
        options = {o.setting_id: [x.option_id for x in o.options] for o in await _options(camera)}
        p = rig.bridge.cam.profile
        expected = {s.param: [str(o.value) for o in s.options] for s in settings_for(p.dialect, p.model, "thermal")}
        assert {k: v for k, v in options.items() if expected.get(k)} == {k: v for k, v in expected.items() if v}
        palette = next(s for s in settings_for(p.dialect, p.model, "thermal") if s.param == "IMG_PALETTE")
        ironbow = next(o for o in palette.options if o.name == "ironbow")
        await camera.set_setting(
            THERMAL, Setting(setting_id="IMG_PALETTE", option=Option(option_id=str(ironbow.value)))
        )
        assert rig.sim.settings["IMG"]["palette"] == "ironbow"
        got = await camera.get_setting(THERMAL, Setting(setting_id="IMG_PALETTE"))
        assert got.option.option_id == str(ironbow.value)
