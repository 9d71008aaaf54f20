"""Every model, with the quirks its profile gives the simulator, driven by the client with nothing
but `model=` (issue 10: the client copes by itself): point, rates, stop, zoom, photo, recording
and reads. What a model cannot do is found from the catalog (its roles), and the client must say
UnsupportedError exactly there; everything else must show in the simulator's own state."""

from __future__ import annotations

import asyncio
import logging
from typing import Any

import pytest

import topgimbal
from topgimbal.errors import UnsupportedError
from topgimbal.protocol import all_models, get_model
from waiting import settled

pytestmark = pytest.mark.loopback

MODELS = sorted(all_models())


def has(model: str, role: str) -> bool:
    dialect, m = get_model(model)
    return dialect.by_role(role, m) is not None


async def settle(read: Any, timeout_s: float = 5.0) -> float:
    """The value `read()` settles at (two reads 0.3 s apart within 0.05; tests/waiting.py)."""
    return await settled("the simulator's axis", read, still=0.05, apart_s=0.3, bound_s=timeout_s)


async def expect(model: str, role: str, call: Any) -> bool:
    """Run `call()` when the model has `role` (True), else check it raises UnsupportedError."""
    if has(model, role):
        await call()
        return True
    with pytest.raises(UnsupportedError):
        await call()
    return False


@pytest.mark.integration
@pytest.mark.parametrize("model", MODELS)
async def test_the_client_drives_every_model_without_flags(sim_factory: Any, model: str, caplog: Any) -> None:
    sim = await sim_factory(model, seed=5)
    _, profile = get_model(model)
    kind = profile.endpoints[0].kind if profile.endpoints[0].kind in ("udp", "tcp") else "udp"
    url = dict(sim.endpoints)[kind]
    async with topgimbal.connect(url, model=model) as cam:
        # -- pointing: closed loop where angles are ignored (C11), sent-only where nothing reports
        if has(model, "attitude"):
            att = await cam.point(10.0, -10.0)
            assert abs(att.yaw_deg - 10) <= 0.5 and abs(att.pitch_deg + 10) <= 0.5
            # point()'s tolerance is on the attitude it was told, not on the live axes (which lag it,
            # and a closed loop, the C11's, stops near the target, not on it): they come to rest, and
            # the camera's report of them then agrees with the simulator's own
            yaw = await settle(lambda: sim.gimbal.yaw_deg)
            pitch = await settle(lambda: sim.gimbal.pitch_deg)
            got = await cam.get_attitude()
            assert abs(got.yaw_deg - yaw) < 0.5 and abs(got.pitch_deg - pitch) < 0.5, (got, yaw, pitch)
        else:  # the C13: point() cannot know when it is there; set_angles() is sent, the gimbal goes
            with pytest.raises(UnsupportedError):
                await cam.point(10.0, -10.0)
            await cam.set_angles(yaw_deg=10.0, pitch_deg=-10.0)
            assert abs(await settle(lambda: sim.gimbal.yaw_deg) - 10) < 0.6
            assert abs(sim.gimbal.pitch_deg + 10) < 0.6

        # -- rates and stop (a C13 stop may coast: the client repeats it)
        y0 = sim.gimbal.yaw_deg
        await cam.rates(yaw_deg_s=5)
        await asyncio.sleep(0.4)
        await cam.stop()
        stopped = await settle(lambda: sim.gimbal.yaw_deg)
        assert stopped > y0 + 0.5, (y0, stopped)  # turned right while the rate was on
        await asyncio.sleep(0.3)
        assert abs(sim.gimbal.yaw_deg - stopped) < 0.05  # and stays stopped

        # -- zoom
        z0 = sim.camera.zoom_pos
        if await expect(model, "zoom_control", lambda: cam.zoom("in")):
            await asyncio.sleep(0.3)
            await cam.zoom("stop")
            if profile.optical_zoom_max > 1:
                assert sim.camera.zoom_pos > z0

        # -- photo and recording (a C11 acts on them only once its video output has started)
        if profile.quirks.get("needs_video_output"):
            with caplog.at_level(logging.WARNING, logger="topgimbal.client"):
                await cam.photo()
            assert sim.camera.photos_taken == 0  # acknowledged, not taken: the client said so
            assert "video output has started" in caplog.text
            sim.camera.video_output = True  # a receiver plays the stream (sim --video does this)
        photos = sim.camera.photos_taken
        if await expect(model, "photo", cam.photo):
            assert sim.camera.photos_taken == photos + 1
        if await expect(model, "recording", cam.start_recording):
            assert sim.camera.recording
            assert await cam.recording() is True
            await cam.stop_recording()
            assert not sim.camera.recording

        # -- reads
        if has(model, "version"):
            assert await cam.version() == profile.identity["version"]
        else:
            with pytest.raises(UnsupportedError):
                await cam.version()

        async def sd() -> None:
            card = await cam.sd_card()
            assert card.present and card.total_mb and card.remaining_mb is not None
            assert card.remaining_mb <= card.total_mb

        await expect(model, "sd_capacity", sd)
        assert cam.stats.timeouts == 0
