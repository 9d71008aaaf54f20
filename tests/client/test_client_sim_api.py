"""Every API method end to end against the simulator, over UDP, TCP and a pty serial line, for a
SkyDroid (C12) and a TOPOTEK (SIP) model."""

from __future__ import annotations

import asyncio

import pytest

import topgimbal
from topgimbal.errors import FieldValueError, UnsupportedError
from waiting import until

pytestmark = pytest.mark.loopback

KINDS = ["udp", "tcp", "serial"]


def endpoint(sim, kind: str) -> str:
    return dict(sim.endpoints)[kind]


MODELS = ["C12", "SIP"]


@pytest.mark.integration
@pytest.mark.parametrize("kind", KINDS)
@pytest.mark.parametrize("model", MODELS)
async def test_core_api(sim_factory, kind, model):
    sim = await sim_factory(model, seed=1)
    async with topgimbal.connect(endpoint(sim, kind), model=model, timeout_s=0.5) as cam:
        # motion in the API convention lands in the simulator's API-convention state
        att = await cam.point(4.0, -3.0, tolerance_deg=0.3)
        assert abs(att.yaw_deg - 4.0) <= 0.3 and abs(att.pitch_deg + 3.0) <= 0.3
        assert abs(sim.gimbal.yaw_deg - 4.0) < 0.5 and abs(sim.gimbal.pitch_deg + 3.0) < 0.5
        got = await cam.get_attitude()
        assert abs(got.pitch_deg - sim.gimbal.pitch_deg) < 0.5

        photos = sim.camera.photos_taken
        await cam.photo()
        assert sim.camera.photos_taken == photos + 1
        await cam.start_recording()
        assert sim.camera.recording and await cam.recording() is True
        await cam.stop_recording()
        assert not sim.camera.recording and await cam.recording() is False
        assert cam.state.recording is not None and cam.state.recording.value is False

        sd = await cam.sd_card()
        assert sd.present and sd.total_mb and sd.remaining_mb is not None and sd.remaining_mb <= sd.total_mb

        samples = []
        async for a in cam.attitude(rate_hz=20):
            samples.append(a)
            if len(samples) == 3:
                break
        assert all(abs(s.yaw_deg - 4.0) < 0.5 for s in samples)
        assert [s.t for s in samples] == sorted(s.t for s in samples)

        assert await cam.version()
        info = await cam.identify()
        assert info["dialect"] == cam.dialect.name and info["version"]
        assert cam.stats.frames_in >= cam.stats.replies > 0  # wiring (a timeout under load is no fault here)


@pytest.mark.integration
@pytest.mark.parametrize("kind", KINDS)
@pytest.mark.parametrize("model", MODELS)
async def test_rest_of_api(sim_factory, model, kind):
    sim = await sim_factory(model, seed=2)
    async with topgimbal.connect(endpoint(sim, kind), model=model, timeout_s=0.5) as cam:
        await cam.rates(yaw_deg_s=5)
        await asyncio.sleep(0.2)
        await cam.stop()
        y = sim.gimbal.yaw_deg
        assert y > 0.2  # turned right (positive) while the rate was on
        await asyncio.sleep(0.2)
        assert abs(sim.gimbal.yaw_deg - y) < 0.5  # and stopped
        await cam.set_mode("lock")
        await cam.set_mode("follow")
        assert cam.state.mode is not None and cam.state.mode.value == "follow"
        await cam.center()
        await cam.zoom("in")
        await cam.zoom("stop")
        await cam.focus("auto")
        await cam.zoom(2)
        net = await cam.network()
        assert net["ip"] and net["gateway"]
        pal = await cam.palette()
        assert pal
        await cam.palette("ironbow")
        assert await cam.palette() == "ironbow"
        assert await cam.thermal("palette") == "ironbow"
        with pytest.raises(FieldValueError):
            await cam.set_angles(yaw_deg=1000)
        with pytest.raises(FieldValueError):
            await cam.set_mode("spin")
        # generic, catalog-driven methods
        m = await cam.cmd.attitude.read()
        assert set(m.fields or {}) >= {"yaw_deg", "pitch_deg", "roll_deg"}
        assert "photo" in dir(cam.cmd)
        raw = await cam.send_raw(cam.build("REC", read=True))
        assert raw is not None and raw.fields == {"state": "stopped"}
        async with cam.rate_control(interval_s=0.05) as joy:
            joy.set(yaw_deg_s=-3)
            await until("two rate frames sent", lambda: joy.sent, lambda n: n >= 2, bound_s=30)
        assert joy.sent >= 2
        if model == "SIP":
            r = await cam.range()
            assert r is None or r > 0
            await cam.set_angles(yaw_deg=2, pitch_deg=1, frame="earth")
            await cam.digital_zoom(2.5)
        else:
            with pytest.raises(UnsupportedError):
                await cam.range()
            with pytest.raises(UnsupportedError):
                await cam.set_angles(yaw_deg=2, frame="earth")
            await cam.digital_zoom(2)
        await cam.set_network(gateway=net["gateway"])


@pytest.mark.integration
async def test_unsolicited_frames_reach_subscribers(sim_factory):
    sim = await sim_factory("SIP", seed=3)
    async with topgimbal.connect(endpoint(sim, "udp"), model="SIP", timeout_s=0.5) as cam:
        seen: list[str] = []
        cam.subscribe(lambda m: seen.append(m.ident))
        await cam.zoom("in")
        await asyncio.sleep(0.3)
        await cam.zoom("stop")
        await until("the zoom report the device sends on its own", lambda: "ZMP" in seen, bound_s=30)
        assert cam.state.zoom is not None


@pytest.mark.integration
async def test_detect_model(sim_factory):
    for model, expect in (("SIP", "SIP"), ("C12", "C12")):
        sim = await sim_factory(model, seed=4)
        async with topgimbal.connect(endpoint(sim, "udp"), model="C12", timeout_s=0.3) as cam:
            assert await cam.detect_model(timeout_s=0.2) == expect


@pytest.mark.integration
async def test_sync_facade_against_simulator():
    from topgimbal.sim import BackgroundSimulator

    with BackgroundSimulator("SIP", seed=5, listen={"udp": [("127.0.0.1", 0)]}) as bg:  # noqa: SIM117 - bg.url
        with topgimbal.Gimbal(bg.url, model="SIP", timeout_s=0.5) as cam:
            cam.start_recording()
            assert cam.recording() is True
            assert bg.call(lambda s: s.camera.recording) is True
            cam.stop_recording()
            att = cam.point(-2.0, 2.0, tolerance_deg=0.3)
            assert abs(att.pitch_deg - 2.0) <= 0.3
            for n, a in enumerate(cam.attitude(rate_hz=20), 1):
                assert abs(a.yaw_deg + 2.0) < 0.5
                if n == 3:
                    break
            assert cam.cmd.recording.read().fields == {"state": "stopped"}
