"""A SIP and a C12 through the bridge, as a ground station's camera screen uses them: the definition
(served over HTTP, parsed by MAVProxy's own parser), settings over PARAM_EXT (the simulator's state is
the truth), the image source, storage format, thermal range, recording time and the stream's
figures."""

from __future__ import annotations

import asyncio
import math
import struct
import urllib.request
from typing import Any

import pytest
from MAVProxy.modules.mavproxy_camera import definition  # installed by `make .venv/.installed`
from pymavlink.dialects.v20 import common as ml

from topgimbal.clock import monotonic

from .conftest import Peer, Rig, eventually
from .virtual import camera_input, in_virtual_time, silence_replies

pytestmark = [pytest.mark.external, pytest.mark.integration]

ACCEPTED, VALUE_UNSUPPORTED, FAILED, IN_PROGRESS = 0, 1, 2, 3


def _value(m: Any) -> float:
    fmt = {1: "<B", 6: "<i", 9: "<f"}[m.param_type]
    return float(struct.unpack(fmt, bytes(m._param_value_raw).ljust(8, b"\0")[: struct.calcsize(fmt)])[0])


async def param_list(peer: Peer, comp: int) -> dict[str, float]:
    last = asyncio.ensure_future(peer.wait("PARAM_EXT_VALUE", lambda m: m.get_srcComponent() == comp
                                           and m.param_index == m.param_count - 1, timeout=15))  # fmt: skip
    await asyncio.sleep(0)
    start = len(peer.messages)
    peer.send(ml.MAVLink_param_ext_request_list_message(1, comp))
    await last
    got = [m for m in peer.messages[start:] if m.get_type() == "PARAM_EXT_VALUE" and m.get_srcComponent() == comp]
    assert len(got) == got[-1].param_count
    return {m.param_id: _value(m) for m in got}


async def param_set(peer: Peer, comp: int, name: str, value: float, wire_type: int = 1) -> list[Any]:
    """PARAM_EXT_SET; every PARAM_EXT_ACK up to the final one."""
    acks: list[Any] = []
    fmt = {1: "<B", 6: "<i", 9: "<f"}[wire_type]
    final = asyncio.ensure_future(peer.wait("PARAM_EXT_ACK", lambda m: m.param_id == name and
                                            (acks.append(m) or m.param_result != IN_PROGRESS), timeout=15))  # fmt: skip
    await asyncio.sleep(0)
    raw = struct.pack(fmt, value if fmt == "<f" else int(value)).ljust(128, b"\0")
    peer.send(ml.MAVLink_param_ext_set_message(1, comp, name.encode(), raw, wire_type))
    await final
    return acks


async def fetch_definition(peer: Peer, comp: int) -> tuple[Any, Any]:
    info = await peer.request(comp, 259, "CAMERA_INFORMATION")
    assert info.cam_definition_uri.startswith("http://127.0.0.1:") and info.cam_definition_version > 0
    data = await asyncio.to_thread(lambda: urllib.request.urlopen(info.cam_definition_uri, timeout=10).read())
    parsed = definition.CameraDefinition(data, locale_name="en_US")
    assert parsed.version == str(info.cam_definition_version)
    return info, parsed


@pytest.mark.parametrize("model", ["SIP", "C12"])
async def test_palette_over_param_ext_changes_the_camera(rig_factory: Any, model: str) -> None:
    rig: Rig = await rig_factory(model)
    peer, sim = rig.peer, rig.sim
    info, parsed = await fetch_definition(peer, 101)
    assert info.flags & 4096 == (4096 if model == "SIP" else 0)  # thermal range only where TMP reports the hottest
    assert "IMG_PALETTE" in parsed.parameters
    options = dict((name, v) for name, v in parsed.parameters["IMG_PALETTE"].options)
    sim.settings["IMG"]["palette"] = "black_hot"  # the camera's own state, changed behind the bridge's back
    values = await param_list(peer, 101)
    assert set(values) == set(parsed.parameters)
    assert values["IMG_PALETTE"] == options["Black hot"]  # read from the camera, not a default
    acks = await param_set(peer, 101, "IMG_PALETTE", options["Ironbow"])
    assert [a.param_result for a in acks] == [IN_PROGRESS, ACCEPTED] and _value(acks[-1]) == options["Ironbow"]
    assert sim.settings["IMG"]["palette"] == "ironbow"
    assert await rig.bridge.cam.call(lambda c: c.palette()) == "ironbow"  # read back over TOP
    # not an option, a wrong type: VALUE_UNSUPPORTED, nothing sent
    bad = max(v for v in options.values()) + 1
    assert (await param_set(peer, 101, "IMG_PALETTE", bad))[-1].param_result == VALUE_UNSUPPORTED
    assert (await param_set(peer, 101, "IMG_PALETTE", 4, wire_type=6))[-1].param_result == VALUE_UNSUPPORTED
    assert sim.settings["IMG"]["palette"] == "ironbow"
    read = asyncio.ensure_future(peer.wait("PARAM_EXT_VALUE", lambda m: m.param_id == "IMG_PALETTE", timeout=10))
    await asyncio.sleep(0)
    peer.send(ml.MAVLink_param_ext_request_read_message(1, 101, b"IMG_PALETTE", -1))
    assert _value(await read) == options["Ironbow"]


async def test_a_setting_of_a_multi_field_command_keeps_the_others(rig_factory: Any) -> None:
    rig: Rig = await rig_factory("C12")
    before = dict(rig.sim.settings["IQE"])
    acks = await param_set(rig.peer, 100, "IQE_BRIGHTNESS", 200, wire_type=6)
    assert acks[-1].param_result == ACCEPTED
    assert rig.sim.settings["IQE"] == {**before, "brightness": 200}
    out_of_range = await param_set(rig.peer, 100, "IQE_BRIGHTNESS", 300, wire_type=6)
    assert out_of_range[-1].param_result == VALUE_UNSUPPORTED and rig.sim.settings["IQE"]["brightness"] == 200


async def test_a_silent_camera_fails_the_set(rig_factory: Any) -> None:
    rig: Rig = await rig_factory("SIP", silence=True)
    await rig.sim.stop()
    acks = await param_set(rig.peer, 101, "IMG_PALETTE", 2)
    assert acks[-1].param_result == FAILED


async def test_source_storage_and_streaming_are_acked_only_when_done(rig_factory: Any) -> None:
    sip: Rig = await rig_factory("SIP")
    assert (await sip.peer.ack(100, 534, 0, 2, 0)).result == ACCEPTED  # thermal alone
    assert sip.sim.settings["PIP"]["mode"] == "sub_only"
    assert (await sip.peer.ack(101, 534, 0, 1, 2)).result == ACCEPTED  # visible with thermal inset
    assert sip.sim.settings["PIP"]["mode"] == "main_sub"
    assert (await sip.peer.ack(100, 534, 0, 3, 0)).result == 2  # NDVI: denied, nothing sent
    assert sip.sim.settings["PIP"]["mode"] == "main_sub"
    sip.sim.camera.sd_used_mb = 100.0
    assert (await sip.peer.ack(100, 526, 1, 1)).result == 3  # no format command in the catalog: UNSUPPORTED
    assert sip.sim.camera.sd_used_mb == 100.0  # nothing was erased
    assert (await sip.peer.ack(100, 2502)).result == ACCEPTED  # its stream runs whenever it is on
    assert (await sip.peer.ack(100, 2503)).result == 3
    c12: Rig = await rig_factory("C12")
    assert (await c12.peer.ack(100, 534, 0, 2, 0)).result == 3  # no source switch in its catalog
    assert (await c12.peer.ack(100, 2503)).result == ACCEPTED and c12.sim.settings["VOM"]["output"] == "off"
    assert (await c12.peer.ack(100, 2502)).result == ACCEPTED and c12.sim.settings["VOM"]["output"] == "on"
    c12.sim.settings["VOM"]["fps"] = 25
    info = await c12.peer.request(100, 269, "VIDEO_STREAM_INFORMATION")
    assert info.framerate == 25 and info.bitrate == c12.sim.settings["VOM"]["bitrate_kbps"] * 1000


async def test_thermal_range_has_finite_temperatures(rig_factory: Any) -> None:
    rig: Rig = await rig_factory("SIP")
    t = await rig.peer.request(101, 277, "CAMERA_THERMAL_RANGE")
    assert math.isfinite(t.max) and 0 <= t.max_point_x <= 1 and 0 <= t.max_point_y <= 1
    # the simulated SIP sends §12.2 reports: the coldest point too, with its position in the picture
    assert math.isfinite(t.min) and t.min <= t.max and 0 <= t.min_point_x <= 1 and 0 <= t.min_point_y <= 1
    ack = await rig.peer.ack(101, 511, 277, 200_000)  # streamed at 5 Hz
    assert ack.result == ACCEPTED
    await rig.peer.wait("CAMERA_THERMAL_RANGE", lambda m: m.get_srcComponent() == 101 and math.isfinite(m.max))
    c12: Rig = await rig_factory("C12")
    assert (await c12.peer.ack(101, 512, 277)).result == 3  # its TMP layout is undocumented


async def test_recording_time_counts_up(rig_factory: Any) -> None:
    rig: Rig = await rig_factory("C12")
    assert (await rig.peer.ack(100, 2500)).result == ACCEPTED
    first = await rig.peer.request(100, 262, "CAMERA_CAPTURE_STATUS")
    await asyncio.sleep(0.5)
    second = await rig.peer.request(100, 262, "CAMERA_CAPTURE_STATUS")
    assert first.video_status == second.video_status == 1
    assert second.recording_time_ms > first.recording_time_ms >= 0
    assert math.isfinite(second.available_capacity) and second.available_capacity > 0
    assert (await rig.peer.ack(100, 2501)).result == ACCEPTED
    await eventually(lambda: not rig.sim.camera.recording, what="the simulator stopped recording")
    stopped = await rig.peer.request(100, 262, "CAMERA_CAPTURE_STATUS")
    assert stopped.video_status == 0 and stopped.recording_time_ms == 0


async def test_hostile_param_ext_requests_are_answered_or_ignored(rig_factory: Any) -> None:
    rig: Rig = await rig_factory("SIP")
    peer, sim = rig.peer, rig.sim
    for pid in (b"\xff\xfe\x00", b"NO_SUCH_PARAM", b""):
        peer.send(ml.MAVLink_param_ext_request_read_message(1, 101, pid, 99))
        peer.send(ml.MAVLink_param_ext_set_message(1, 101, pid, b"\x01", 1))
    nan = struct.pack("<f", float("nan")).ljust(128, b"\0")
    for ptype in (9, 200, 0):  # float NaN, no such type: VALUE_UNSUPPORTED
        acks = await param_set_raw(peer, 101, "IMG_PALETTE", nan, ptype)
        assert acks[-1].param_result == VALUE_UNSUPPORTED
    # a flood of sets: bounded, every one answered, the camera ends at one of the values sent
    start = len(peer.messages)
    for i in range(30):
        peer.send(ml.MAVLink_param_ext_set_message(1, 101, b"IMG_PALETTE", bytes([i % 10]).ljust(128, b"\0"), 1))

    def finals() -> list[Any]:
        return [m for m in peer.messages[start:] if m.get_type() == "PARAM_EXT_ACK" and m.param_result != IN_PROGRESS]

    await eventually(lambda: len(finals()) == 30, 60, "an answer to every set")
    assert {a.param_result for a in finals()} <= {ACCEPTED, FAILED}
    assert sum(a.param_result == ACCEPTED for a in finals()) >= 1
    values = await param_list(peer, 101)  # still serving, and it says what the camera has
    palette = next(s for s in rig.bridge.cameras[1].params.settings.values() if s.param == "IMG_PALETTE")
    assert palette.to_api(values["IMG_PALETTE"]) == sim.settings["IMG"]["palette"]


async def param_set_raw(peer: Peer, comp: int, name: str, raw: bytes, ptype: int) -> list[Any]:
    acks: list[Any] = []
    final = asyncio.ensure_future(peer.wait("PARAM_EXT_ACK", lambda m: m.param_id == name and
                                            (acks.append(m) or m.param_result != IN_PROGRESS), timeout=15))  # fmt: skip
    await asyncio.sleep(0)
    peer.send(ml.MAVLink_param_ext_set_message(1, comp, name.encode(), raw, ptype))
    await final
    return acks


@pytest.mark.virtual
@in_virtual_time
async def test_virtual_a_silent_camera_fails_the_set_after_its_retries(vrig_maker: Any) -> None:
    """The same in virtual time, the camera silent rather than gone: the set (an absolute
    set-point: retried) goes out 1 + retries times, timeout_s apart, and the final PARAM_EXT_ACK
    is FAILED when the last try times out, never ACCEPTED. The camera did get it (only its answers
    are lost): FAILED says "not confirmed", not "not done"."""
    timeout_s, retries = 1.0, 2
    vrig = await vrig_maker("SIP", silence_s=10.0, timeout_s=timeout_s, retries=retries)
    await eventually(lambda: vrig.bridge.cam.answering, 10, "camera answering")
    sent = camera_input(vrig.sim)
    before = vrig.sim.settings["IMG"]["palette"]
    silence_replies(vrig.sim, 60.0)
    t_set = monotonic()
    acks = await param_set(vrig.peer, 101, "IMG_PALETTE", 2)
    t_failed = monotonic()
    assert [a.param_result for a in acks] == [IN_PROGRESS, FAILED]
    tries = [t for t, data in sent if data[6:10] == b"wIMG"]
    assert len(tries) == 1 + retries, sent
    assert tries == pytest.approx([tries[0] + k * timeout_s for k in range(1 + retries)], abs=1e-6)
    assert tries[0] - t_set < 0.05
    assert t_failed - tries[-1] == pytest.approx(timeout_s, abs=0.05)
    assert vrig.bridge.cam.answering  # silence_s (10 s) not reached: the link itself is still up
    assert vrig.sim.settings["IMG"]["palette"] != before  # carried out, only not confirmed


@pytest.mark.virtual
@in_virtual_time
async def test_virtual_recording_time_counts_the_seconds_recorded(vrig_maker: Any) -> None:
    """The same in virtual time: CAMERA_CAPTURE_STATUS counts the recording's seconds exactly."""
    vrig = await vrig_maker("C12", stream_hz=5.0, attitude_hz=1.0)
    assert (await vrig.peer.ack(100, 2500)).result == ACCEPTED
    first = await vrig.peer.request(100, 262, "CAMERA_CAPTURE_STATUS")
    t1 = monotonic()
    await asyncio.sleep(10.0)
    second = await vrig.peer.request(100, 262, "CAMERA_CAPTURE_STATUS")
    t2 = monotonic()  # 10 s and a request's round trip later
    assert first.video_status == second.video_status == 1
    assert second.recording_time_ms - first.recording_time_ms == pytest.approx((t2 - t1) * 1000, abs=5)
    assert (await vrig.peer.ack(100, 2501)).result == ACCEPTED
    stopped = await vrig.peer.request(100, 262, "CAMERA_CAPTURE_STATUS")
    assert stopped.video_status == 0 and stopped.recording_time_ms == 0 and not vrig.sim.camera.recording


@in_virtual_time
async def test_virtual_a_read_asked_again_while_the_camera_answers_is_not_queued_again(vrig_maker: Any) -> None:
    """A client resends PARAM_EXT_REQUEST_READ while a slow camera answers (MAVSDK every ~0.4 s): the
    read already on its way answers them all, one camera round trip and one PARAM_EXT_VALUE, rather
    than one queued camera read per resend (their answers came ever later, and MAVSDK took them for
    answers to the wrong requests)."""
    timeout_s, retries = 1.0, 1
    vrig = await vrig_maker("SIP", silence_s=30.0, timeout_s=timeout_s, retries=retries)
    await eventually(lambda: vrig.bridge.cam.answering, 10, "camera answering")
    params = vrig.bridge.cameras[1].params
    sent = camera_input(vrig.sim)
    silence_replies(vrig.sim, 60.0)  # the camera hears, its answers are lost: each read takes its retries
    start = len(vrig.peer.messages)
    for _ in range(6):  # 1.5 s of resends, within the one read's 2 s (1 + retries tries, timeout_s apart)
        vrig.peer.send(ml.MAVLink_param_ext_request_read_message(1, 101, b"IMG_PALETTE", -1))
        await asyncio.sleep(0.3)
    await asyncio.sleep(10.0)  # whatever was queued has long been answered
    values = [
        m for m in vrig.peer.messages[start:] if m.get_type() == "PARAM_EXT_VALUE" and m.param_id == "IMG_PALETTE"
    ]
    reads = [t for t, data in sent if data[6:10] == b"rIMG"]
    assert len(values) == 1 and params.coalesced == 5, (len(values), params.coalesced)
    assert len(reads) == 1 + retries, reads
    assert not params.reading  # nothing left marked: the next read asks the camera again
