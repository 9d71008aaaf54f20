"""Inbound MAVLink by message name (issue 44): `Node.on(names, handler)` hands a message only to
the parts registered for its name, refuses a name that is no MAVLink message, and every part the
bridge registers says in `MESSAGES` each message its `on_message` reads (an AST check, so a part
that learns a new message cannot silently never hear it). Virtual tier: a `memory:` link."""

from __future__ import annotations

import ast
import asyncio
import inspect
import textwrap
from typing import Any

import pytest

from topgimbal.links.mav import mavlink
from topgimbal.mavlink import (
    autopilot_streams,
    camera_feed,
    commands,
    ftp,
    gimbal_device,
    gimbal_manager,
    params_ext,
    reboots,
    vehicle,
)
from topgimbal.mavlink.node import Node

from .virtual import MemPeer, fresh_name, in_virtual_time

pytestmark = pytest.mark.virtual

ml = mavlink()
NAMES = {cls.msgname for cls in ml.mavlink_map.values()}
PARTS = [
    autopilot_streams.AutopilotStreams, camera_feed.AutopilotState, commands.Dispatcher, ftp.FtpServer,
    gimbal_device.GimbalDevice, gimbal_manager.GimbalManager, params_ext.ParamsExt, reboots.RebootWatch,
    vehicle.Vehicles,
]  # fmt: skip


def test_an_unknown_name_is_refused_with_the_name():
    node = Node(1, [])
    with pytest.raises(ValueError, match="'GIMBAL_SET_ATITUDE' is not a MAVLink message"):
        node.on(["HEARTBEAT", "GIMBAL_SET_ATITUDE"], lambda m: None)


@in_virtual_time
async def test_a_message_reaches_only_the_handlers_of_its_name_and_every_tap():
    name = fresh_name("dispatch")
    node = Node(1, [f"memory:{name}"])
    got: dict[str, list[str]] = {"time": [], "both": [], "tap": []}
    node.on("SYSTEM_TIME", lambda m: got["time"].append(m.get_type()))
    node.on(("SYSTEM_TIME", "ATTITUDE"), lambda m: got["both"].append(m.get_type()))
    node.subscribe(lambda m: got["tap"].append(m.get_type()))
    await node.start()
    peer = await MemPeer().join(name, heartbeat=True)
    try:
        peer.send(ml.MAVLink_system_time_message(1_700_000_000_000_000, 1000))
        peer.send(ml.MAVLink_attitude_message(1000, 0.1, 0.2, 0.3, 0, 0, 0))
        peer.send(ml.MAVLink_gps_raw_int_message(0, 3, 0, 0, 0, 0, 0, 0, 0, 10))
        for _ in range(100):
            if len(got["tap"]) >= 4:
                break
            await asyncio.sleep(0.01)
    finally:
        peer.close()
        await node.close()
    assert got == {
        "time": ["SYSTEM_TIME"],
        "both": ["SYSTEM_TIME", "ATTITUDE"],
        "tap": ["HEARTBEAT", "SYSTEM_TIME", "ATTITUDE", "GPS_RAW_INT"],
    }


def _names_read(cls: type) -> set[str]:
    """The MAVLink message names written as strings in `cls.on_message` (what it compares the
    message's type with)."""
    tree = ast.parse(textwrap.dedent(inspect.getsource(cls.on_message)))
    return {n.value for n in ast.walk(tree) if isinstance(n, ast.Constant) and n.value in NAMES}


@pytest.mark.parametrize("cls", PARTS, ids=lambda c: c.__name__)
def test_each_part_registers_for_every_message_its_handler_reads(cls: Any):
    declared = set(cls.MESSAGES)
    assert declared <= NAMES, f"{cls.__name__}.MESSAGES names no MAVLink message: {sorted(declared - NAMES)}"
    missing = _names_read(cls) - declared
    assert not missing, (
        f"{cls.__name__}.on_message reads {sorted(missing)}, not in its MESSAGES: it would never hear them"
    )
