"""The bridge never serves a camera as a model it is not (issue 35.2): `topgimbal mavlink --model
C12` against a SIP refuses to start (exit 2, naming the SIP); a camera that turns out to be another
model after the bridge started is reported failed and its commands are refused before sending."""

from __future__ import annotations

import asyncio
import logging
from typing import Any

import pytest
from pymavlink.dialects.v20 import common as ml

from topgimbal.cli.main import main
from topgimbal.clock import monotonic
from topgimbal.mavlink import Bridge, BridgeConfig
from topgimbal.sim import BackgroundSimulator, Simulator

from .conftest import Peer, eventually
from .virtual import (
    HealthLog,
    MemPeer,
    camera_input,
    fresh_name,
    in_virtual_time,
    silence_replies,
    start_bridge,
    start_camera,
)

pytestmark = pytest.mark.loopback

GIMBAL = 154


def test_the_cli_refuses_to_serve_a_sip_as_a_c12(capsys):
    with BackgroundSimulator("SIP", seed=35, listen={"udp": [("127.0.0.1", 0)]}) as sip:
        code = main(["mavlink", "--url", sip.url, "--model", "C12", "--mavlink", "udpin:127.0.0.1:0"])
        targets = sip.call(lambda s: (s.gimbal.axis("yaw").target, s.gimbal.axis("pitch").target))
    err = capsys.readouterr().err
    assert code == 2 and "SIP" in err and "--model auto" in err and len(err.splitlines()) == 1, err
    assert targets == pytest.approx((0.0, 0.0))


async def test_a_camera_that_turns_out_to_be_another_model_is_not_served(caplog) -> None:
    sim = Simulator("SIP")
    await sim.start(udp=[("127.0.0.1", 0)])
    bridge = Bridge(BridgeConfig(url=sim.url, model="C12", endpoints=["udpin:127.0.0.1:0"], silence_s=0.6,
                                 timeout_s=0.3, retries=1))  # fmt: skip
    caplog.set_level(logging.INFO, logger="topgimbal.mavlink")
    try:
        await bridge.start(camera_wait_s=0.5)
        peer = await Peer().connect(bridge.addresses[0][1])  # type: ignore[index]
        await eventually(lambda: bool(bridge.cam.wrong_model), 10)
        assert "SIP" in bridge.cam.wrong_model and not bridge.cam.answering
        await peer.wait(
            "HEARTBEAT", lambda m: m.get_srcComponent() == GIMBAL and m.system_status == ml.MAV_STATE_CRITICAL
        )
        ack = await peer.ack(GIMBAL, ml.MAV_CMD_DO_GIMBAL_MANAGER_PITCHYAW, -20, 10)
        assert ack.result != ml.MAV_RESULT_ACCEPTED
        await asyncio.sleep(0.3)
        assert (sim.gimbal.axis("yaw").target, sim.gimbal.axis("pitch").target) == pytest.approx((0.0, 0.0))
        errors = [r for r in caplog.records if r.levelno >= logging.ERROR and "not served" in r.getMessage()]
        assert len(errors) == 1
        peer.close()
    finally:
        await bridge.close()
        await sim.stop()


async def test_a_healthy_camera_is_logged_as_info_not_a_warning(caplog) -> None:
    """Issue 35.6: "camera ... answers" is good news."""
    sim = Simulator("C12")
    await sim.start(udp=[("127.0.0.1", 0)])
    bridge = Bridge(BridgeConfig(url=sim.url, model="C12", endpoints=["udpin:127.0.0.1:0"], timeout_s=0.3))
    caplog.set_level(logging.INFO, logger="topgimbal.mavlink")
    try:
        await bridge.start(camera_wait_s=0.5)
        await eventually(lambda: bridge.cam.answering, 10)
        answers = [r for r in caplog.records if "answers" in r.getMessage()]
        assert answers and all(r.levelno == logging.INFO for r in answers)
        assert not [r for r in caplog.records if r.levelno >= logging.WARNING]
    finally:
        await bridge.close()
        await sim.stop()


@pytest.mark.parametrize("model", ["SIP", "C20"])
def test_model_auto_serves_the_camera_as_what_it_says(capsys, caplog, model):
    """Detection is quiet: the device's answers to the other models' identity queries are what
    `--model auto` asks for, not a wrong model to warn about (a C20 answers the MOD asked while the
    client still stands in as a C12; that used to print "looks like a C20, not a C12")."""
    with BackgroundSimulator(model, seed=36, listen={"udp": [("127.0.0.1", 0)]}) as cam:
        code = main(
            ["mavlink", "--url", cam.url, "--model", "auto", "--mavlink", "udpin:127.0.0.1:0", "--seconds", "1"]
        )
    out, err = capsys.readouterr()
    assert code == 0 and f"mavlink bridge: {cam.url} ({model})" in out, out
    # (what a user's terminal shows of the log: stderr there; under pytest the records)
    said = err + "".join(r.getMessage() for r in caplog.records if r.levelno >= logging.WARNING)
    assert "looks like" not in said and "not a C12" not in said and "--model" not in said, said


def test_several_cameras_refuse_one_that_is_another_model(capsys):
    """Issue 35 item 2: `mavlink --camera` with a SIP declared as a C12 beside a real C12 exits 2,
    naming the camera and the model it is, before anything is served or sent."""
    with (
        BackgroundSimulator("C12", seed=37, listen={"udp": [("127.0.0.1", 0)]}) as c12,
        BackgroundSimulator("SIP", seed=38, listen={"udp": [("127.0.0.1", 0)]}) as sip,
    ):
        code = main(["mavlink", "--mavlink", "udpin:127.0.0.1:0", "--camera", f"left={c12.url},C12",
                     "--camera", f"right={sip.url},C12", "--seconds", "1"])  # fmt: skip
        targets = sip.call(lambda s: (s.gimbal.axis("yaw").target, s.gimbal.axis("pitch").target))
    captured = capsys.readouterr()
    err = captured.err
    assert code == 2 and "mavlink bridge" not in captured.out, captured
    assert len(err.splitlines()) == 1 and f"camera right ({sip.url})" in err and "SIP" in err, err
    assert "right=URL,auto" in err and "left" not in err.replace(f"camera right ({sip.url})", ""), err
    assert targets == pytest.approx((0.0, 0.0))


def test_several_cameras_with_model_auto_serve_each_as_what_it_says(capsys, caplog):
    with (
        BackgroundSimulator("C12", seed=39, listen={"udp": [("127.0.0.1", 0)]}) as c12,
        BackgroundSimulator("SIP", seed=40, listen={"udp": [("127.0.0.1", 0)]}) as sip,
    ):
        code = main(["mavlink", "--mavlink", "udpin:127.0.0.1:0", "--camera", f"left={c12.url},C12",
                     "--camera", f"right={sip.url},auto", "--seconds", "1"])  # fmt: skip
    out, err = capsys.readouterr()
    assert code == 0 and "left (C12): gimbal 154" in out and "right (SIP): gimbal 171" in out, out
    said = err + "".join(r.getMessage() for r in caplog.records if r.levelno >= logging.WARNING)
    assert "looks like" not in said and "not a C12" not in said, said  # detection is quiet


def _gimbal_states(peer: MemPeer) -> list[int]:
    return [m.system_status for m in peer.messages if m.get_type() == "HEARTBEAT" and m.get_srcComponent() == GIMBAL]


def _verdicts_at_health_changes(made: Any) -> list[tuple[bool, str]]:
    """(answering, the client's model check status) at each of the bridge's health changes."""
    seen: list[tuple[bool, str]] = []
    made.cam.on_health(lambda up: seen.append((up, made.cam.client.model_check.status)))
    return seen


@pytest.mark.virtual
@in_virtual_time
async def test_virtual_a_camera_that_turns_out_to_be_another_model_stays_unserved(caplog: Any) -> None:
    """The same in virtual time, watched for a minute of the product's own timers (silence 3 s,
    1 s x 3, pings, reconnects): never reported healthy, not even before the model check's verdict
    (MAV_STATE_BOOT until it, CRITICAL from it on); nothing sent after the verdict (no attitude stream
    request again, no renewal, no ping) and nothing that moves the gimbal ever; one error line when
    found, and each refused command a throttled warning without a traceback."""
    caplog.set_level(logging.INFO, logger="topgimbal")
    sim, url = await start_camera("SIP")
    sent = camera_input(sim)  # from before the bridge's client opens
    link = fresh_name("gcs")
    made = await start_bridge(url, "C12", link)
    health = HealthLog(made)
    peer = await MemPeer().join(link)
    try:
        await eventually(lambda: bool(made.cam.wrong_model), 10)
        assert "SIP" in made.cam.wrong_model and not made.cam.answering
        await peer.wait(
            "HEARTBEAT", lambda m: m.get_srcComponent() == GIMBAL and m.system_status == ml.MAV_STATE_CRITICAL
        )
        for yaw in (-20, 10, 30):
            ack = await peer.ack(GIMBAL, ml.MAV_CMD_DO_GIMBAL_MANAGER_PITCHYAW, -20, yaw)
            assert (ack.result, ack.result_param2) == (ml.MAV_RESULT_FAILED, 5)  # 5: the camera is another model
            await asyncio.sleep(20.0)
        assert (sim.gimbal.axis("yaw").target, sim.gimbal.axis("pitch").target) == pytest.approx((0.0, 0.0))
        # all before the verdict: the model check's identity reads and at most the bridge's attitude
        # stream request (asked at once, beside the check; dropped if the verdict comes before its
        # turn to go); since, nothing (no stream request again, no renewal, no ping), and nothing
        # that moves the gimbal ever
        verdict_t = health.changes[0][0]
        frames = [(t, data[6:10]) for t, data in sent]
        assert {f for _, f in frames if f[:1] == b"w"} <= {b"wGAA"}, frames
        assert {f for _, f in frames if f[:1] == b"r"} <= {b"rVER", b"rMOD", b"rHWV"}, frames
        assert frames and all(t <= verdict_t for t, _ in frames), (verdict_t, frames)
        assert [up for _, up in health.changes] == [False], health.changes  # never healthy
        states = _gimbal_states(peer)
        first_critical = states.index(ml.MAV_STATE_CRITICAL)
        assert set(states[:first_critical]) == {ml.MAV_STATE_BOOT}, states
        assert set(states[first_critical:]) == {ml.MAV_STATE_CRITICAL}, states
        errors = [r for r in caplog.records if r.levelno >= logging.ERROR]
        assert [r.getMessage().startswith(f"camera {url}: not served:") for r in errors] == [True], errors
        assert not [r for r in caplog.records if r.exc_info], "no traceback for an expected refusal"
        refused = [r for r in caplog.records if "refused" in r.getMessage() and r.name == "topgimbal.mavlink"]
        assert len(refused) == 3 and all(r.levelno == logging.WARNING for r in refused)  # 20 s apart: each one
        stops = [r for r in caplog.records if "stops sending" in r.getMessage()]
        assert len(stops) == 1 and "C12" in stops[0].getMessage()
    finally:
        peer.close()
        await made.close()
        await sim.stop()


@pytest.mark.virtual
@in_virtual_time
async def test_virtual_refusals_of_a_wrong_model_are_one_throttled_line(caplog: Any) -> None:
    """Commands to a camera that is another model, one a second: one WARNING line per 10 s, the next
    saying how many were left out; no traceback, no per-command INFO line."""
    caplog.set_level(logging.INFO, logger="topgimbal.mavlink")
    sim, url = await start_camera("SIP")
    link = fresh_name("gcs")
    made = await start_bridge(url, "C12", link)
    peer = await MemPeer().join(link)
    try:
        await eventually(lambda: bool(made.cam.wrong_model), 10)
        caplog.clear()
        for i in range(12):  # 12 commands over 11 s: a line at the first, the next at 10 s (9 left out)
            ack = await peer.ack(GIMBAL, ml.MAV_CMD_DO_GIMBAL_MANAGER_PITCHYAW, -20, i)
            assert (ack.result, ack.result_param2) == (ml.MAV_RESULT_FAILED, 5)
            await asyncio.sleep(1.0)
        lines = [r for r in caplog.records if r.name == "topgimbal.mavlink" and "1000" in r.getMessage()]
        assert [r.levelno for r in lines] == [logging.WARNING, logging.WARNING], [r.getMessage() for r in lines]
        assert "SIP" in lines[0].getMessage() and "more like it not logged" not in lines[0].getMessage()
        assert lines[1].getMessage().endswith("(9 more like it not logged)"), lines[1].getMessage()
        assert not [r for r in caplog.records if r.exc_info or r.levelno >= logging.ERROR]
    finally:
        peer.close()
        await made.close()
        await sim.stop()


@pytest.mark.virtual
@in_virtual_time
async def test_virtual_a_camera_of_the_declared_model_is_active_only_after_the_check(caplog: Any) -> None:
    """A C12 served as a C12: BOOT until the model check says so, then ACTIVE; the one health change
    (healthy) comes with the verdict ok, never while it is pending."""
    caplog.set_level(logging.INFO, logger="topgimbal")
    sim, url = await start_camera("C12")
    link = fresh_name("gcs")
    made = await start_bridge(url, "C12", link, camera_wait_s=0.0)
    seen = _verdicts_at_health_changes(made)
    peer = await MemPeer().join(link)
    try:
        await eventually(lambda: made.cam.answering, 10)
        await peer.wait(
            "HEARTBEAT", lambda m: m.get_srcComponent() == GIMBAL and m.system_status == ml.MAV_STATE_ACTIVE
        )
        await asyncio.sleep(30.0)
        assert seen == [(True, "ok")]
        states = _gimbal_states(peer)
        first_active = states.index(ml.MAV_STATE_ACTIVE)
        assert set(states[:first_active]) <= {ml.MAV_STATE_BOOT}, states
        assert set(states[first_active:]) == {ml.MAV_STATE_ACTIVE}, states
        assert not [r for r in caplog.records if r.levelno >= logging.WARNING]
    finally:
        peer.close()
        await made.close()
        await sim.stop()


@pytest.mark.virtual
@in_virtual_time
async def test_virtual_a_camera_silent_at_first_that_turns_out_to_be_another_model_is_never_healthy(
    caplog: Any,
) -> None:
    """A SIP silent for its first 10 s (off, booting): the model check on connect hears nothing
    (unknown), the link is declared down at 3 s; the client keeps pinging, and the SIP's first
    answer sends the verdict back to pending and the check runs again, so the camera goes from
    CRITICAL to not served without a moment of ACTIVE, and nothing is sent after that verdict."""
    caplog.set_level(logging.INFO, logger="topgimbal")
    sim, url = await start_camera("SIP")
    t0 = monotonic()
    silence_replies(sim, 10.0)
    sent = camera_input(sim)
    link = fresh_name("gcs")
    made = await start_bridge(url, "C12", link, camera_wait_s=0.0)
    seen = _verdicts_at_health_changes(made)
    peer = await MemPeer().join(link)
    try:
        await eventually(lambda: bool(made.cam.wrong_model), 30)
        found = len(sent)
        assert "SIP" in made.cam.wrong_model and monotonic() >= t0 + 10.0
        await asyncio.sleep(30.0)
        assert [data[6:10] for _, data in sent[found:]] == []  # nothing since the verdict
        assert seen == [(False, "unknown")], seen  # declared down at 3 s; never healthy
        states = _gimbal_states(peer)
        first_critical = states.index(ml.MAV_STATE_CRITICAL)
        assert set(states[:first_critical]) == {ml.MAV_STATE_BOOT}, states
        assert set(states[first_critical:]) == {ml.MAV_STATE_CRITICAL}, states
        assert not [r for r in caplog.records if "answers" in r.getMessage() and r.name == "topgimbal.mavlink"]
    finally:
        peer.close()
        await made.close()
        await sim.stop()
