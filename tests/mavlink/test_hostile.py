"""A careless or hostile peer: NaN and infinite parameters, retransmissions with NaN, byte streams
split anywhere, floods of NEUTRAL set-points, garbage rates. Each case once broke the bridge."""

from __future__ import annotations

import asyncio
import logging
import math
from typing import Any

import pytest
from pymavlink.dialects.v20 import common as ml

from topgimbal.autopilot.vehicle import MAX_SYSTEMS, Vehicles
from topgimbal.geo.aim import Geodetic
from topgimbal.mavlink.commands import BUSY_LOG_EVERY_S, Command, Dispatcher
from topgimbal.mavlink.node import Node
from topgimbal.mavlink.pointing import Setpoint
from topgimbal.mavlink.quaternion import from_euler_deg

from .conftest import NAN, Peer, eventually
from .virtual import in_virtual_time

pytestmark = pytest.mark.loopback

GIMBAL, CAMERA = 154, 100
INF = math.inf


def count_applies(rig: Any) -> list[Setpoint]:
    """Every set-point the bridge sends to the camera (commands and streams alike)."""
    pointer = rig.bridge.pointer
    applied: list[Setpoint] = []
    original = pointer.apply

    async def apply(sp: Setpoint, **kw: Any) -> None:
        applied.append(sp)
        await original(sp, **kw)

    pointer.apply = apply
    return applied


async def test_a_retransmission_with_nan_parameters_acts_once(rig: Any) -> None:
    """MAVSDK sends DO_GIMBAL_MANAGER_PITCHYAW with NaN rates and retransmits with confirmation
    1, 2, ... Two NaN floats are never equal (and hash apart), so each copy used to move the
    gimbal again and get its own ACCEPTED."""
    p = rig.peer
    applied = count_applies(rig)
    first = await p.ack(GIMBAL, ml.MAV_CMD_DO_GIMBAL_MANAGER_PITCHYAW, -20, 30, NAN, NAN)
    assert first.result == ml.MAV_RESULT_ACCEPTED
    for confirmation in (1, 2, 3):
        again = await p.ack(GIMBAL, ml.MAV_CMD_DO_GIMBAL_MANAGER_PITCHYAW, -20, 30, NAN, NAN,
                            confirmation=confirmation)  # fmt: skip
        assert (again.result, again.result_param2) == (first.result, first.result_param2)
    assert len(applied) == 1, applied
    # a new command (different values) still acts
    assert (await p.ack(GIMBAL, ml.MAV_CMD_DO_GIMBAL_MANAGER_PITCHYAW, -10, 30, NAN, NAN)).result == 0
    assert len(applied) == 2


BAD_NUMBERS = [
    # (what, component, command, params): each used to raise int(NaN) / int(inf) in the bridge and
    # come back FAILED with result_param2 4 (a bridge error) and a traceback in the log.
    ("pitchyaw flags inf", GIMBAL, ml.MAV_CMD_DO_GIMBAL_MANAGER_PITCHYAW, (-5, 0, NAN, NAN, INF)),
    ("pitchyaw device id inf", GIMBAL, ml.MAV_CMD_DO_GIMBAL_MANAGER_PITCHYAW, (-5, 0, NAN, NAN, 0, 0, INF)),
    ("configure sysid inf", GIMBAL, ml.MAV_CMD_DO_GIMBAL_MANAGER_CONFIGURE, (INF, INF, -1, -1)),
    ("configure sysid 1e12", GIMBAL, ml.MAV_CMD_DO_GIMBAL_MANAGER_CONFIGURE, (1e12, 3, -1, -1)),
    ("configure secondary 300", GIMBAL, ml.MAV_CMD_DO_GIMBAL_MANAGER_CONFIGURE, (-2, -2, 300, 1)),
    ("roi mode nan", GIMBAL, ml.MAV_CMD_DO_SET_ROI, (NAN,)),
    ("roi sysid nan", GIMBAL, ml.MAV_CMD_DO_SET_ROI_SYSID, (NAN,)),
    ("request message nan", GIMBAL, ml.MAV_CMD_REQUEST_MESSAGE, (NAN,)),
    ("request message inf", CAMERA, ml.MAV_CMD_REQUEST_MESSAGE, (INF,)),
    ("request message -1", CAMERA, ml.MAV_CMD_REQUEST_MESSAGE, (-1,)),
    ("set interval nan id", GIMBAL, ml.MAV_CMD_SET_MESSAGE_INTERVAL, (NAN, 1000)),
    ("set interval inf us", GIMBAL, ml.MAV_CMD_SET_MESSAGE_INTERVAL, (281, INF)),
    ("get interval nan", GIMBAL, ml.MAV_CMD_GET_MESSAGE_INTERVAL, (NAN,)),
    ("zoom type nan", CAMERA, ml.MAV_CMD_SET_CAMERA_ZOOM, (NAN, 50)),
    ("zoom type inf", CAMERA, ml.MAV_CMD_SET_CAMERA_ZOOM, (INF, 50)),
    ("zoom step nan", CAMERA, ml.MAV_CMD_SET_CAMERA_ZOOM, (0, NAN)),  # was: zoomed out, ACCEPTED
    ("focus type nan", CAMERA, ml.MAV_CMD_SET_CAMERA_FOCUS, (NAN, 1)),
    ("camera mode nan", CAMERA, ml.MAV_CMD_SET_CAMERA_MODE, (0, NAN)),
    ("images inf", CAMERA, ml.MAV_CMD_IMAGE_START_CAPTURE, (0, 1, INF, 0)),
    ("capture sequence inf", CAMERA, ml.MAV_CMD_IMAGE_START_CAPTURE, (0, 0, 1, INF)),
    ("image index inf", CAMERA, ml.MAV_CMD_REQUEST_CAMERA_IMAGE_CAPTURE, (INF,)),
    ("stream id inf", CAMERA, ml.MAV_CMD_REQUEST_VIDEO_STREAM_INFORMATION, (INF,)),
]


async def test_bad_numbers_are_denied_with_nothing_applied(rig: Any) -> None:
    p = rig.peer
    manager = rig.bridge.manager
    for what, compid, command, params in BAD_NUMBERS:
        ack = await p.ack(compid, command, *params)
        assert (ack.result, ack.result_param2) == (ml.MAV_RESULT_DENIED, 0), what
    # a refused CONFIGURE changed nothing (1e12 used to be stored, and every GIMBAL_MANAGER_STATUS
    # after it failed to encode)
    assert (manager.primary, manager.secondary) == ((0, 0), (0, 0))
    status = await p.request(GIMBAL, ml.MAVLINK_MSG_ID_GIMBAL_MANAGER_STATUS, "GIMBAL_MANAGER_STATUS")
    assert status.primary_control_sysid == 0
    # the same commands with sane numbers still work
    ack = await p.ack(GIMBAL, ml.MAV_CMD_DO_GIMBAL_MANAGER_CONFIGURE, -2, -2, -1, -1)
    assert ack.result == ml.MAV_RESULT_ACCEPTED and manager.primary == (p.mav.srcSystem, p.mav.srcComponent)
    assert (await p.ack(GIMBAL, ml.MAV_CMD_SET_MESSAGE_INTERVAL, 281, 200000)).result == ml.MAV_RESULT_ACCEPTED


async def test_roi_sysid_reads_the_device_from_param2_and_roi_location_needs_a_place(rig: Any) -> None:
    p = rig.peer
    # MAV_CMD_DO_SET_ROI_SYSID: param1 is the system to follow, param2 the gimbal device. System 2
    # used to be read as "gimbal device 2" and DENIED.
    ack = await p.ack(GIMBAL, ml.MAV_CMD_DO_SET_ROI_SYSID, 2, 0)
    assert ack.result == ml.MAV_RESULT_TEMPORARILY_REJECTED  # nothing heard from system 2 yet
    assert (await p.ack(GIMBAL, ml.MAV_CMD_DO_SET_ROI_SYSID, 2, 7)).result == ml.MAV_RESULT_DENIED
    autopilot = Peer(sysid=1, compid=1)
    await autopilot.connect(rig.bridge.addresses[0][1])
    try:
        autopilot.send(ml.MAVLink_attitude_message(0, 0.0, 0.0, 0.0, 0, 0, 0))
        autopilot.send(ml.MAVLink_global_position_int_message(0, 473977420, 85455940, 500000, 100000, 0, 0, 0, 0))
        await eventually(lambda: rig.bridge.vehicles.fix() is not None)
        applied = count_applies(rig)
        # NaN places used to aim at NaN: no frame went out, yet the ack said ACCEPTED
        for lat, lon, alt in ((NAN, NAN, 400.0), (47.4, 8.5, NAN), (95.0, 8.5, 400.0), (47.4, INF, 400.0)):
            ack = await p.ack(GIMBAL, ml.MAV_CMD_DO_SET_ROI_LOCATION, 0, 0, 0, 0, lat, lon, alt)
            assert ack.result == ml.MAV_RESULT_DENIED, (lat, lon, alt)
        assert applied == [] and rig.bridge.manager.roi is None
    finally:
        autopilot.close()


def test_parser_buffer_stays_small_when_every_chunk_splits_a_packet() -> None:
    """pymavlink frees its buffer only when a chunk ends at a packet boundary: a TCP or serial
    stream split elsewhere every time used to keep every byte ever received."""
    node = Node(1, ["tcpin:127.0.0.1:0"])
    got: list[Any] = []
    node.subscribe(got.append)
    enc = ml.MAVLink(None, srcSystem=250, srcComponent=1)
    one = ml.MAVLink_heartbeat_message(6, 8, 0, 0, 4, 3).pack(enc)
    link = node.links[0]
    node._on_data(link, "peer", one[:1])
    n = 3000
    for _ in range(n):
        node._on_data(link, "peer", one[1:] + one[:1])
    assert len(got) == n
    parser = node._parsers[(id(link), "peer")]
    assert len(parser.buf) - parser.buf_index == 1  # the next packet's first byte, still waiting
    assert len(parser.buf) < 300  # was n * len(one) = 63 000 bytes


async def test_neutral_takes_precedence_over_a_quaternion(rig_factory: Any) -> None:
    rig = await rig_factory("C12", range_hz=0.0)
    s, p = rig.sim, rig.peer
    assert (await p.ack(GIMBAL, ml.MAV_CMD_DO_GIMBAL_MANAGER_PITCHYAW, -30, 40, NAN, NAN)).result == 0
    await eventually(lambda: abs(s.gimbal.pitch_deg + 30) < 0.5 and abs(s.gimbal.yaw_deg - 40) < 0.5, 15)
    # NEUTRAL with a quaternion elsewhere: MAVLink says NEUTRAL wins (it used to aim at the quaternion)
    q = list(from_euler_deg(0, -45, 60))
    p.send(ml.MAVLink_gimbal_manager_set_attitude_message(1, GIMBAL, ml.GIMBAL_MANAGER_FLAGS_NEUTRAL, 0, q,
                                                          NAN, NAN, NAN))  # fmt: skip
    await eventually(lambda: abs(s.gimbal.pitch_deg) < 0.5 and abs(s.gimbal.yaw_deg) < 0.5, 15)


async def test_a_flood_of_neutral_set_points_is_one_request(rig_factory: Any) -> None:
    """300 NEUTRAL set-points in one datagram: latest wins, one centre request (each used to start
    its own task, every one sending the centre command to the camera, hundreds queued)."""
    rig = await rig_factory("C12", range_hz=0.0)
    s, p = rig.sim, rig.peer
    center = rig.bridge.cam.profile.ident("gimbal_control")
    before = len(s.received)
    enc = ml.MAVLink(None, srcSystem=1, srcComponent=1)
    neutral = ml.MAVLink_gimbal_device_set_attitude_message(
        1, GIMBAL, ml.GIMBAL_DEVICE_FLAGS_NEUTRAL, [NAN] * 4, NAN, NAN, NAN
    )
    burst = b"".join(neutral.pack(enc) for _ in range(300))
    assert p.transport is not None
    p.transport.sendto(burst)
    await eventually(lambda: rig.bridge.node.messages_in >= 300)

    def centres() -> int:
        return sum(1 for f in s.received[before:] if f.ident == center)

    await eventually(lambda: centres() >= 1)
    await asyncio.sleep(0.5)  # the old bridge had sent a dozen more by now
    assert centres() == 1


def infinite_rates(kind: str) -> Any:
    """A gimbal setpoint of `kind` whose angular velocities are infinite."""
    rates = (INF, -INF, INF)
    if kind == "manager_attitude":
        return ml.MAVLink_gimbal_manager_set_attitude_message(1, GIMBAL, 0, 0, [0.0] * 4, *rates)
    if kind == "device_attitude":
        return ml.MAVLink_gimbal_device_set_attitude_message(1, GIMBAL, 0, [0.0] * 4, *rates)
    return ml.MAVLink_gimbal_manager_set_pitchyaw_message(1, GIMBAL, 0, 0, NAN, NAN, INF, -INF)


@pytest.mark.parametrize("kind", ["manager_attitude", "device_attitude", "manager_pitchyaw"])
async def test_infinite_rates_are_no_rates(rig: Any, kind: str) -> None:
    """An infinite angular velocity used to be clamped to the model's top speed: the gimbal spun."""
    p = rig.peer
    applied = count_applies(rig)
    garbage = infinite_rates(kind)
    p.send(garbage)
    await asyncio.sleep(0.3)  # the old bridge had started turning by now
    sane = ml.MAVLink_gimbal_manager_set_pitchyaw_message(1, GIMBAL, 0, 0, math.radians(-10), NAN, NAN, NAN)
    p.send(sane)
    await eventually(lambda: len(applied) > 0)
    assert len(applied) == 1 and applied[0].pitch_deg == pytest.approx(-10) and not applied[0].is_rate


class _Wire:
    """A fake MAVLink link that keeps what the node sends."""

    def __init__(self) -> None:
        self.parser = ml.MAVLink(None)
        self.acks: list[Any] = []
        self.dropped_out = 0

    def send(self, data: bytes) -> None:
        self.acks += [m for m in self.parser.parse_buffer(data) or [] if m.get_type() == "COMMAND_ACK"]


async def test_a_command_flood_beyond_the_in_flight_limit_is_refused_with_one_log_line(
    caplog: pytest.LogCaptureFixture,
) -> None:
    node = Node(1, [])
    wire = _Wire()
    node.links.append(wire)  # type: ignore[arg-type]
    dispatcher = Dispatcher(max_inflight=4)
    release = asyncio.Event()

    async def slow(cmd: Command) -> None:
        await release.wait()

    dispatcher.register(node.component(GIMBAL, "gimbal"), 31000, slow)
    gcs = ml.MAVLink(None, srcSystem=255, srcComponent=190)
    parser = ml.MAVLink(None)
    with caplog.at_level(logging.WARNING, logger="topgimbal.mavlink"):
        for i in range(200):
            packed = ml.MAVLink_command_long_message(1, GIMBAL, 31000, 0, i, 0, 0, 0, 0, 0, 0).pack(gcs)
            for m in parser.parse_buffer(packed) or []:
                dispatcher.on_message(m)
        await asyncio.sleep(0)

    def results() -> list[int]:  # IN_PROGRESS acks may come in between on a slow machine
        return [a.result for a in wire.acks if a.result != ml.MAV_RESULT_IN_PROGRESS]

    assert results() == [ml.MAV_RESULT_TEMPORARILY_REJECTED] * 196
    busy = [r for r in caplog.records if "in progress (the limit)" in r.getMessage()]
    assert len(busy) == 1  # was one warning per refused command
    assert dispatcher.busy_rejected == 196
    release.set()
    await eventually(lambda: len(results()) == 200)
    assert results()[196:] == [ml.MAV_RESULT_ACCEPTED] * 4
    await dispatcher.close()


def test_many_vehicles_on_the_network_never_evict_our_own() -> None:
    """More than MAX_SYSTEMS vehicles reporting positions (a swarm, or a spoofer) used to push our own
    vehicle's fix out between its own updates: ROI and earth-frame yaw were then refused."""
    vehicles = Vehicles(1, {GIMBAL, CAMERA})
    parser = ml.MAVLink(None)

    def position_from(sysid: int) -> Any:
        enc = ml.MAVLink(None, srcSystem=sysid, srcComponent=1)
        data = ml.MAVLink_global_position_int_message(0, 473977420, 85455940, 500000, 100000, 0, 0, 0, 0).pack(enc)
        return parser.parse_buffer(data)[0]

    vehicles.on_message(position_from(1))
    for sysid in range(2, 2 + 3 * MAX_SYSTEMS):
        vehicles.on_message(position_from(sysid))
    assert vehicles.fix() is not None
    assert vehicles.fix(2 + 3 * MAX_SYSTEMS - 1) is not None  # the latest other system too
    assert vehicles.fix(2) is None  # the oldest others went: still bounded
    assert len(vehicles._fixes) == MAX_SYSTEMS


async def test_a_burst_of_set_points_during_roi_stops_it_once(rig: Any) -> None:
    manager = rig.bridge.manager
    manager.roi = Geodetic(47.4, 8.5, 400.0)  # as after MAV_CMD_DO_SET_ROI_LOCATION
    enc = ml.MAVLink(None, srcSystem=255, srcComponent=190)
    parser = ml.MAVLink(None)
    data = ml.MAVLink_gimbal_manager_set_pitchyaw_message(1, GIMBAL, 0, 0, -0.2, NAN, NAN, NAN).pack(enc)
    msg = parser.parse_buffer(data)[0]
    for _ in range(300):  # what one datagram full of set-points does, synchronously
        manager.on_message(msg)
    stops = [t for t in asyncio.all_tasks() if "_stop_roi" in repr(t.get_coro())]
    assert len(stops) == 1  # was 300
    await eventually(lambda: manager.roi is None)


async def test_a_broadcast_request_is_answered_only_by_components_that_send_the_message(rig: Any) -> None:
    """A broadcast REQUEST_MESSAGE CAMERA_INFORMATION used to get UNSUPPORTED from the gimbal too: a
    ground station that takes the first ack for a broadcast could conclude there is no camera."""
    p = rig.peer
    p.messages.clear()
    for msgid in (ml.MAVLINK_MSG_ID_CAMERA_INFORMATION, ml.MAVLINK_MSG_ID_GIMBAL_MANAGER_INFORMATION):
        p.send(ml.MAVLink_command_long_message(1, 0, ml.MAV_CMD_REQUEST_MESSAGE, 0, msgid, 0, 0, 0, 0, 0, 0))
    p.send(ml.MAVLink_command_long_message(1, 0, ml.MAV_CMD_REQUEST_CAMERA_INFORMATION, 0, 1, 0, 0, 0, 0, 0, 0))
    # both answers, in whatever order (the cameras' wait for the definition pacer, camdef/pacing.py)
    await eventually(
        lambda: (
            {(m.get_type(), m.get_srcComponent()) for m in p.messages}
            >= {("CAMERA_INFORMATION", 101), ("GIMBAL_MANAGER_INFORMATION", GIMBAL)}
        ),
        10,
        "the thermal camera's CAMERA_INFORMATION and the GIMBAL_MANAGER_INFORMATION",
    )
    # a later command that needs the camera: every ack for the broadcasts has been sent by then
    assert (await p.ack(GIMBAL, ml.MAV_CMD_DO_GIMBAL_MANAGER_PITCHYAW, -5, 0, NAN, NAN)).result == 0
    acks = sorted(
        (m.command, m.get_srcComponent(), m.result)
        for m in p.messages
        if m.get_type() == "COMMAND_ACK" and m.command != ml.MAV_CMD_DO_GIMBAL_MANAGER_PITCHYAW
    )
    assert acks == sorted(
        [
            (ml.MAV_CMD_REQUEST_MESSAGE, CAMERA, 0),
            (ml.MAV_CMD_REQUEST_MESSAGE, 101, 0),
            (ml.MAV_CMD_REQUEST_MESSAGE, GIMBAL, 0),
            (ml.MAV_CMD_REQUEST_CAMERA_INFORMATION, CAMERA, 0),
            (ml.MAV_CMD_REQUEST_CAMERA_INFORMATION, 101, 0),
        ]
    )


async def test_the_busy_warning_comes_again_after_its_period_counting_what_it_left_out(
    caplog: pytest.LogCaptureFixture,
) -> None:
    """The refusals' warning (logthrottle.ThrottledLog): one line per BUSY_LOG_EVERY_S, the next
    saying how many were refused since the last line and in all."""
    node = Node(1, [])
    node.links.append(_Wire())  # type: ignore[arg-type]
    dispatcher = Dispatcher(max_inflight=1)
    now = [1000.0]
    dispatcher.busy_log.clock = lambda: now[0]
    release = asyncio.Event()

    async def slow(cmd: Command) -> None:
        await release.wait()

    dispatcher.register(node.component(GIMBAL, "gimbal"), 31000, slow)
    gcs = ml.MAVLink(None, srcSystem=255, srcComponent=190)
    parser = ml.MAVLink(None)
    seq = iter(range(1000))

    def flood(n: int) -> None:
        for _ in range(n):
            packed = ml.MAVLink_command_long_message(1, GIMBAL, 31000, 0, next(seq), 0, 0, 0, 0, 0, 0).pack(gcs)
            for m in parser.parse_buffer(packed) or []:
                dispatcher.on_message(m)

    def lines() -> list[str]:
        return [r.getMessage() for r in caplog.records if "TEMPORARILY_REJECTED" in r.getMessage()]

    with caplog.at_level(logging.WARNING, logger="topgimbal.mavlink"):
        flood(6)  # one runs, five refused
        now[0] += BUSY_LOG_EVERY_S - 0.5
        flood(3)
        assert len(lines()) == 1 and lines()[0].endswith("(1 rejected since the last such line, 1 in all)")
        now[0] += 0.5
        flood(2)
    assert len(lines()) == 2 and lines()[1].endswith("(8 rejected since the last such line, 9 in all)"), lines()
    assert dispatcher.busy_rejected == 10  # the last one left out: within the new period
    release.set()
    await asyncio.sleep(0)


@pytest.mark.virtual
@in_virtual_time
async def test_virtual_a_flood_of_neutral_set_points_stays_one_request(vrig_maker: Any) -> None:
    """The same in virtual time, watched for 30 s rather than 0.5 s: still one centre request."""
    vrig = await vrig_maker("C12", range_hz=0.0, stream_hz=5.0, attitude_hz=1.0)
    s = vrig.sim
    center = vrig.bridge.cam.profile.ident("gimbal_control")
    before = len(s.received)
    enc = ml.MAVLink(None, srcSystem=1, srcComponent=1)
    neutral = ml.MAVLink_gimbal_device_set_attitude_message(
        1, GIMBAL, ml.GIMBAL_DEVICE_FLAGS_NEUTRAL, [NAN] * 4, NAN, NAN, NAN
    )
    assert vrig.peer.end is not None
    assert vrig.peer.end.send(b"".join(neutral.pack(enc) for _ in range(300)))  # one chunk, as one datagram
    await eventually(lambda: vrig.bridge.node.messages_in >= 300)
    await asyncio.sleep(30.0)
    assert sum(1 for f in s.received[before:] if f.ident == center) == 1


@pytest.mark.virtual
@pytest.mark.parametrize("kind", ["manager_attitude", "device_attitude", "manager_pitchyaw"])
@in_virtual_time
async def test_virtual_infinite_rates_are_no_rates(vrig_maker: Any, kind: str) -> None:
    """The same in virtual time, watched for 10 s: the garbage is never applied, the sane one once."""
    vrig = await vrig_maker("C12", stream_hz=5.0, attitude_hz=1.0)
    p = vrig.peer
    applied = count_applies(vrig)
    garbage = infinite_rates(kind)
    yaw_before = vrig.sim.gimbal.yaw_deg
    p.send(garbage)
    await asyncio.sleep(10.0)
    assert applied == [] and vrig.sim.gimbal.yaw_deg == pytest.approx(yaw_before, abs=0.01)
    p.send(ml.MAVLink_gimbal_manager_set_pitchyaw_message(1, GIMBAL, 0, 0, math.radians(-10), NAN, NAN, NAN))
    await asyncio.sleep(10.0)
    assert len(applied) == 1 and applied[0].pitch_deg == pytest.approx(-10) and not applied[0].is_rate
