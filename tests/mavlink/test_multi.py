"""Several cameras behind one MAVLink bridge (mavlink/multi.py): component ids allocated per camera,
and MAVSDK 4.x (a ground station) lists two distinct gimbals and cameras, each driving its own
simulator only."""

from __future__ import annotations

import asyncio
import sys

import pytest
from mavsdk.asyncio import ComponentType, Configuration
from mavsdk.asyncio.plugins.camera import CameraAsync
from mavsdk.asyncio.plugins.gimbal import GimbalAsync, GimbalMode, SendMode

from topgimbal.mavlink.bridge import BridgeConfigError
from topgimbal.mavlink.multi import MultiBridge, allocate
from topgimbal.sim import Simulator

from .conftest import eventually, keep, mavsdk_session
from .test_mavsdk import _until

pytestmark = [pytest.mark.external, pytest.mark.integration]


def test_component_ids_are_allocated_in_order() -> None:
    three = allocate([("a", "udp://x:1", "C12"), ("b", "udp://x:2", "SIP"), ("c", "udp://x:3", "C12")], thermal=False)
    assert [a.gimbal_compid for a in three] == [154, 171, 172]
    assert [a.camera_compids for a in three] == [[100], [101], [102]]
    thermal = allocate([("a", "udp://x:1", "C12"), ("b", "udp://x:2", "C12")])
    assert [a.camera_compids for a in thermal] == [[100, 101], [102, 103]]
    six = allocate([(f"c{i}", "udp://x:1", "C12") for i in range(6)], thermal=False)
    assert [a.camera_compids for a in six][-1] == [105]
    with pytest.raises(BridgeConfigError, match="need 8 camera component ids"):
        allocate([(f"c{i}", "udp://x:1", "C12") for i in range(4)])
    with pytest.raises(BridgeConfigError, match="gimbal component ids"):
        allocate([(f"c{i}", "udp://x:1", "C12") for i in range(7)], cameras_wanted=False)
    assert allocate([("a", "udp://x:1", "C12")], cameras_wanted=False)[0].camera_compids == []


@pytest.mark.cage(240)  # MAVSDK can hang its caller (conftest.mavsdk_session)
async def test_two_cameras_through_one_bridge_are_two_in_mavsdk() -> None:
    sims = [Simulator("C12"), Simulator("C12")]
    for s in sims:
        await s.start(udp=[("127.0.0.1", 0)])
    multi = MultiBridge([("left", sims[0].url, "C12"), ("right", sims[1].url, "C12")],
                        endpoints=["udpin:127.0.0.1:0"], thermal=False, silence_s=1.0, timeout_s=0.5)  # fmt: skip
    await multi.start()
    try:
        port = multi.addresses[0][1]  # type: ignore[index]
        cfg = Configuration.create_with_component_type(ComponentType.GROUND_STATION)
        async with mavsdk_session(cfg) as mavsdk:
            await mavsdk.add_any_connection(f"udpout://127.0.0.1:{port}")
            await eventually(lambda: mavsdk._mavsdk.system_count() > 0, 20, "MAVSDK sees the system")
            system = (await mavsdk.get_systems())[0]
            gimbal, camera = GimbalAsync(system), CameraAsync(system)
            keep(gimbal, camera)
            glist = await _until(gimbal.subscribe_gimbal_list(), lambda g: len(g.gimbals) >= 2, 30)
            assert glist is not None, "two gimbals not discovered"
            assert sorted(g.gimbal_manager_component_id for g in glist.gimbals) == [154, 171]
            by_comp = {g.gimbal_manager_component_id: g.gimbal_id for g in glist.gimbals}
            assert len(set(by_comp.values())) == 2

            clist = await _until(camera.subscribe_camera_list(), lambda c: len(c.cameras) >= 2, 30)
            assert clist is not None, "two cameras not discovered"
            assert sorted(c.component_id for c in clist.cameras) == [100, 101]

            # the second gimbal moves the second simulator only
            await gimbal.set_angles(by_comp[171], 0.0, -20.0, 15.0, GimbalMode.YAW_FOLLOW, SendMode.ONCE)
            await eventually(lambda: abs(sims[1].gimbal.yaw_deg - 15) <= 0.5, 20, "the right camera turned")
            assert sims[0].gimbal.yaw_deg == 0.0 and sims[0].gimbal.pitch_deg == 0.0
            # the first camera component photographs with the first simulator only
            await camera.take_photo(100)
            await eventually(lambda: sims[0].camera.photos_taken >= 1, 10)
            await asyncio.sleep(0.5)
            assert sims[0].camera.photos_taken == 1 and sims[1].camera.photos_taken == 0
    finally:
        await multi.close()
        for s in sims:
            await s.stop()


async def test_bad_camera_set_is_refused_before_anything_opens() -> None:
    with pytest.raises(BridgeConfigError):
        MultiBridge([], endpoints=["udpin:127.0.0.1:0"])
    with pytest.raises(BridgeConfigError, match="camera component ids"):
        MultiBridge([(f"c{i}", "udp://127.0.0.1:9", "C12") for i in range(4)], endpoints=["udpin:127.0.0.1:0"])


async def _cli(*args: str) -> tuple[int, str, str]:
    proc = await asyncio.create_subprocess_exec(
        sys.executable, "-m", "topgimbal.cli.main", "mavlink", *args,
        stdout=asyncio.subprocess.PIPE, stderr=asyncio.subprocess.PIPE,
    )  # fmt: skip
    out, err = await asyncio.wait_for(proc.communicate(), 60)
    return proc.returncode or 0, out.decode(), err.decode()


async def test_cli_serves_several_cameras_and_refuses_too_many() -> None:
    sims = [Simulator("C12"), Simulator("SIP")]
    for s in sims:
        await s.start(udp=[("127.0.0.1", 0)])
    try:
        code, out, err = await _cli("--mavlink", "udpin:127.0.0.1:0", "--camera", f"a={sims[0].url},C12",
                                    "--camera", f"b={sims[1].url},SIP", "--seconds", "1")  # fmt: skip
        assert code == 0, err
        assert "a (C12): gimbal 154, cameras 100,101" in out and "b (SIP): gimbal 171, cameras 102" in out
        four = [x for i in range(4) for x in ("--camera", f"c{i}={sims[0].url},C12")]
        code, out, err = await _cli("--mavlink", "udpin:127.0.0.1:0", *four)
        assert code == 2 and "camera component ids" in err and "Traceback" not in err
        code, out, err = await _cli("--mavlink", "udpin:127.0.0.1:0", "--camera", "a=udp://127.0.0.1:1")
        assert code == 2 and "NAME=URL,MODEL" in err
    finally:
        for s in sims:
            await s.stop()
