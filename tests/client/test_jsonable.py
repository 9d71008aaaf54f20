"""The one JSON encoding of SDK results (client/jsonable.py): CLI `--json`, the console's pushes
and HTTP answers and the Zenoh server's replies agree, and none prints NaN as an invalid literal."""

from __future__ import annotations

import argparse
import dataclasses
import datetime
import enum
import json
import math
from typing import NamedTuple

import pytest

from topgimbal.cli.device_output import show
from topgimbal.client.jsonable import dumps, jsonable
from topgimbal.client.remote_keys import decode_result, encode_result
from topgimbal.client.state import GimbalAttitude, SdCard, Stamped
from topgimbal.console.ops import jsonable as console_jsonable
from topgimbal.console.peer import dumps as peer_dumps
from topgimbal.protocol import get_model, parse_frame

pytestmark = pytest.mark.loopback


def strict_loads(text: str) -> object:
    """`json.loads` as a browser's JSON.parse reads: NaN, Infinity and -Infinity are errors."""

    def refuse(name: str) -> object:
        raise ValueError(f"invalid JSON literal {name}")

    return json.loads(text, parse_constant=refuse)


class Mode(enum.Enum):
    AUTO = "auto"


class Level(enum.IntEnum):
    HIGH = 2


class Point(NamedTuple):
    x_m: float
    y_m: float


@dataclasses.dataclass
class Plain:
    name: str
    when: datetime.datetime


def message():  # type: ignore[no-untyped-def]
    dialect = get_model("C12")[0]
    return dialect.decode(parse_frame("#TPUG2wPTZ006A"))


def test_non_finite_floats_are_null_at_any_depth() -> None:
    value = {"a": math.nan, "b": [math.inf, -math.inf, 1.5], "c": {"d": math.nan}}
    assert jsonable(value) == {"a": None, "b": [None, None, 1.5], "c": {"d": None}}
    assert strict_loads(dumps(value)) == {"a": None, "b": [None, None, 1.5], "c": {"d": None}}


def test_each_kind_of_value_has_one_rule() -> None:
    when = datetime.datetime(2026, 11, 28, 6, 0, 1, 500000)
    assert jsonable(when) == "2026-11-28T06:00:01.500000"
    assert jsonable(datetime.date(2026, 11, 28)) == "2026-11-28"
    assert jsonable(Mode.AUTO) == "auto"
    assert jsonable(Level.HIGH) == 2 and type(jsonable(Level.HIGH)) is int
    assert jsonable(b"\x01A\xff") == "\x01A\xff"
    assert jsonable(Point(1.0, math.nan)) == {"x_m": 1.0, "y_m": None}
    assert jsonable(Plain("p", when)) == {"name": "p", "when": "2026-11-28T06:00:01.500000"}
    assert jsonable({3, 1, 2}) == [1, 2, 3]
    assert jsonable(SdCard(True, 10, None)) == {"present": True, "remaining_mb": 10, "total_mb": None}
    assert jsonable(object()).startswith("<object")  # never fails on an unexpected type


def test_a_message_and_a_frame_are_not_encoded_as_tuples() -> None:
    m = message()
    assert jsonable(m) == m.to_dict()
    assert jsonable(m.frame) == "#TPUG2wPTZ006A"


def test_cli_json_prints_valid_json_for_nan(capsys: pytest.CaptureFixture[str]) -> None:
    show(argparse.Namespace(json=True), {"attitude": GimbalAttitude(math.nan, 1.0, math.inf), "range_m": math.nan})
    out = strict_loads(capsys.readouterr().out)
    assert out == {
        "attitude": {"yaw_deg": None, "pitch_deg": 1.0, "roll_deg": None, "t": 0.0, "wall": 0.0, "source": "GAC"},
        "range_m": None,
    }


def test_console_pushes_valid_json_for_nan() -> None:
    text = peer_dumps({"type": "state", "state": Stamped(GimbalAttitude(math.nan, 2.0, 0.0), 1.0, 2.0)})
    assert strict_loads(text) == {
        "type": "state",
        "state": {
            "value": {"yaw_deg": None, "pitch_deg": 2.0, "roll_deg": 0.0, "t": 0.0, "wall": 0.0, "source": "GAC"},
            "t": 1.0,
            "wall": 2.0,
        },
    }


def test_cli_console_and_zenoh_agree() -> None:
    """The same results give the same JSON on all three (the Zenoh server keeps its own Message
    shape, which its client turns back into a Message)."""
    results: list[object] = [GimbalAttitude(1.0, math.nan, 0.0), SdCard(True, 1, 2), {"x": math.inf}, 3.5, None, "s"]
    for r in results:
        assert console_jsonable(r) == jsonable(r) == encode_result(r)
    m = message()
    back = decode_result("request", encode_result(m), "C12")
    assert jsonable(back) == jsonable(m)
