"""links/json_shape.py: pymavlink messages <-> the JSON BlueOS's mavlink-server puts on Zenoh
(rust-mavlink 0.16's serde form), both ways, and what it refuses."""

from __future__ import annotations

import json
import math
from typing import Any

import pytest

from topgimbal.links import json_shape as js
from topgimbal.links.mav import mavlink

pytestmark = pytest.mark.loopback

mav = mavlink()


CAMERA_INFO = (1, [65] * 32, [66] * 32, 3, 16.0, 12.0, 10.0, 1920, 1080, 0, 0x1FF, 2, b"http://x/c12.xml", 0, 154)


def _wire(msg: Any, sysid: int = 1, compid: int = 154, seq: int = 7) -> Any:
    """The message as a peer receives it (header set by the encoder)."""
    enc = mav.MAVLink(None, srcSystem=sysid, srcComponent=compid)
    enc.seq = seq
    return mav.MAVLink(None).parse_buffer(bytes(msg.pack(enc)))[0]


def _round_trip(msg: Any) -> tuple[str, str]:
    text = js.dumps(js.to_obj(_wire(msg)))
    header, back = js.loads(text)
    again = mav.MAVLink(None).parse_buffer(js.encode(header, back))[0]
    return text, js.dumps(js.to_obj(again))


def test_heartbeat_in_rust_mavlinks_serde_form() -> None:
    hb = _wire(mav.MAVLink_heartbeat_message(26, 8, 128 | 8, 0, 4, 3), 1, 171, 42)
    obj = js.to_obj(hb)
    assert obj["header"] == {"system_id": 1, "component_id": 171, "sequence": 42, "message_id": 0}
    assert list(obj["header"]) == ["system_id", "component_id", "sequence", "message_id"]
    # wire order (custom_mode, a uint32, first), the tag first, `type` named `mavtype`
    assert list(obj["message"]) == ["type", "custom_mode", "mavtype", "autopilot", "base_mode", "system_status",
                                    "mavlink_version"]  # fmt: skip
    assert obj["message"]["type"] == "HEARTBEAT"
    assert obj["message"]["mavtype"] == {"type": "MAV_TYPE_GIMBAL"}
    assert obj["message"]["system_status"] == {"type": "MAV_STATE_ACTIVE"}
    # MAV_MODE_FLAG is declared high bit first: bitflags writes SAFETY_ARMED before GUIDED_ENABLED
    assert obj["message"]["base_mode"] == "MAV_MODE_FLAG_SAFETY_ARMED | MAV_MODE_FLAG_GUIDED_ENABLED"


def test_bit_masks_low_bit_first_empty_and_unknown_bits_dropped() -> None:
    msg = mav.MAVLink_gimbal_device_attitude_status_message(0, 0, 5, 4 | 32 | 0x8000, [1, 0, 0, 0], 0, 0, 0, 0)
    m = js.to_obj(_wire(msg))["message"]
    assert m["flags"] == "GIMBAL_DEVICE_FLAGS_ROLL_LOCK | GIMBAL_DEVICE_FLAGS_YAW_IN_VEHICLE_FRAME"
    assert m["failure_flags"] == ""  # nothing set: bitflags' empty text
    assert m["q"] == [1.0, 0.0, 0.0, 0.0]


@pytest.mark.parametrize(
    "msg",
    [
        mav.MAVLink_heartbeat_message(26, 8, 128 | 8, 0, 4, 3),
        mav.MAVLink_command_long_message(1, 171, 1000, 0, -30.0, 25.0, math.nan, math.nan, 0, 0, 0),
        mav.MAVLink_command_ack_message(1000, 0, 0, 0, 255, 190),
        mav.MAVLink_camera_information_message(*CAMERA_INFO),
        mav.MAVLink_param_ext_value_message(b"CAM_MODE", b"\x01\x00", 1, 10, 0),
        mav.MAVLink_gimbal_device_attitude_status_message(1, 2, 5, 36, [0.9, 0.1, -0.2, 0.3], 0.1, 0.2, 0.3, 4),
    ],
    ids=lambda m: m.get_type(),
)
def test_round_trip(msg: Any) -> None:
    first, second = _round_trip(msg)
    assert first == second


def test_strings_arrays_and_enums_in_camera_information() -> None:
    info = mav.MAVLink_camera_information_message(1, [65] * 32, [66] * 32, 3, 16.0, 12.0, 10.0, 1920, 1080, 0,
                                                  2 | 4, 2, b"http://x/c.xml", 0, 154)  # fmt: skip
    m = js.to_obj(_wire(info))["message"]
    assert m["cam_definition_uri"] == "http://x/c.xml"  # char[140]: up to the first NUL
    assert m["vendor_name"] == [65] * 32  # uint8_t[32]: numbers, not text
    assert m["flags"] == "CAMERA_CAP_FLAGS_CAPTURE_IMAGE | CAMERA_CAP_FLAGS_HAS_MODES"


def test_command_long_from_json_with_enum_nan_and_missing_fields() -> None:
    text = json.dumps({"header": {"system_id": 255, "component_id": 190, "sequence": 9},
                       "message": {"type": "COMMAND_LONG", "target_system": 1, "target_component": 171,
                                   "command": {"type": "MAV_CMD_DO_GIMBAL_MANAGER_PITCHYAW"},
                                   "param1": -30.0, "param2": 25, "param3": float("nan")}})  # fmt: skip
    header, msg = js.loads(text)
    assert header == {"system_id": 255, "component_id": 190, "sequence": 9}
    got = mav.MAVLink(None).parse_buffer(js.encode(header, msg))[0]
    assert (got.get_srcSystem(), got.get_srcComponent(), got.get_seq()) == (255, 190, 9)
    assert got.command == 1000 and got.param1 == -30.0 and got.param2 == 25.0 and math.isnan(got.param3)
    assert got.param4 == 0.0 and got.confirmation == 0  # missing: zero


def test_unknown_enum_value_is_the_plain_number_both_ways() -> None:
    ack = _wire(mav.MAVLink_command_ack_message(1000, 77, 0, 0, 255, 190))  # 77: no MAV_RESULT entry
    m = js.to_obj(ack)["message"]
    assert m["result"] == 77
    _, back = js.from_obj({"header": {"system_id": 1, "component_id": 1}, "message": m})
    assert back.result == 77


def test_per_field_payloads_as_mavlink_server_publishes_them() -> None:
    m = js.to_obj(_wire(mav.MAVLink_command_long_message(1, 171, 1000, 0, math.nan, 1, 2, 3, 4, 5, 6)))["message"]
    fields = dict(js.field_payloads(m))
    assert fields["type"] == '"COMMAND_LONG"'
    assert json.loads(fields["command"]) == {"type": "MAV_CMD_DO_GIMBAL_MANAGER_PITCHYAW"}
    assert fields["param1"] == "null"  # serde_json's to_value turns NaN into null
    assert fields["param2"] == "1.0"


@pytest.mark.parametrize(
    ("payload", "says"),
    [
        (b"not json", "not JSON"),
        (b"\xff\xfe\x00", "not JSON"),
        (b"[" * 10_000, "not JSON"),
        (b" " * (js.MAX_IN_BYTES + 1), "more than"),
        (b"[1, 2]", "expected"),
        (b'{"header": {"system_id": 1, "component_id": 1}, "message": {"type": "NOPE"}}', "NOPE"),
        (b'{"header": {"system_id": 300, "component_id": 1}, "message": {"type": "HEARTBEAT"}}', "system_id"),
        (
            b'{"header": {"system_id": 1, "component_id": 1, "message_id": 5}, "message": {"type": "HEARTBEAT"}}',
            "message_id",
        ),
        (
            b'{"header": {"system_id": 1, "component_id": 1}, "message": {"type": "HEARTBEAT", "custom_mode": "x"}}',
            "expected a number",
        ),
        (
            b'{"header": {"system_id": 1, "component_id": 1}, "message": {"type": "HEARTBEAT", "custom_mode": -1}}',
            "range",
        ),
        (
            b'{"header": {"system_id": 1, "component_id": 1}, "message": {"type": "HEARTBEAT", "mavtype": {"type": "X"}}}',
            "MAV_TYPE",
        ),
        (
            b'{"header": {"system_id": 1, "component_id": 1}, "message": {"type": "HEARTBEAT", "base_mode": "NOPE"}}',
            "no flag",
        ),
        (
            b'{"header": {"system_id": 1, "component_id": 1}, "message": {"type": "GIMBAL_DEVICE_ATTITUDE_STATUS", '
            b'"q": [1, 0]}}',
            "list of 4",
        ),
        (
            b'{"header": {"system_id": 1, "component_id": 1}, "message": {"type": "PARAM_EXT_SET", "param_id": 5}}',
            "string",
        ),
    ],
)
def test_bad_input_raises_shape_error(payload: bytes, says: str) -> None:
    with pytest.raises(js.ShapeError, match=says):
        js.loads(payload)


def test_flags_given_as_text_and_hex() -> None:
    _, hb = js.from_obj({"header": {"system_id": 1, "component_id": 1},
                         "message": {"type": "HEARTBEAT", "base_mode": "MAV_MODE_FLAG_GUIDED_ENABLED | 0x80"}})  # fmt: skip
    assert hb.base_mode == 8 | 128
