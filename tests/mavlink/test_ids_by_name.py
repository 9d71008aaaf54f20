"""The bridge writes MAVLink command and message ids by name, from pymavlink (`links.mav.mav_id`,
`links.mav.msg_id`), never as integer literals: a literal can silently name the wrong command, and a
name can be grepped in the spec."""

from __future__ import annotations

import ast
import importlib
from pathlib import Path

import pytest
from pymavlink.dialects.v20 import common as ml

from topgimbal.links import mav as _mav

pytestmark = pytest.mark.virtual

PKG = Path(__file__).resolve().parents[2] / "src" / "topgimbal"
MAVLINK_SRC = [*(PKG / "mavlink").glob("*.py"), *(PKG / "links").glob("*.py")]  # the bridge and its links
ID_PREFIXES = ("MSG_", "CMD_", "MAV_CMD_")
ID_TABLES = ("LOCAL_MESSAGES", "LEGACY_REQUESTS", "WANTED")  # tables of ids


def _int_literals(node: ast.AST) -> list[int]:
    return [
        n.value
        for n in ast.walk(node)
        if isinstance(n, ast.Constant) and isinstance(n.value, int) and not isinstance(n.value, bool)
    ]


def _id_parts(value: ast.expr) -> list[ast.AST]:
    """Where ids are in an assigned value: all of it, but of a {command: (message, parameter)} table
    only the keys and each value's first item (the parameter's index is a plain number)."""
    if isinstance(value, ast.Dict):
        firsts = [v.elts[0] if isinstance(v, ast.Tuple) and v.elts else v for v in value.values]
        return [k for k in value.keys if k is not None] + firsts
    return [value]


def _targets(node: ast.Assign | ast.AnnAssign) -> list[str]:
    targets = node.targets if isinstance(node, ast.Assign) else [node.target]
    return [n.id for t in targets for n in ast.walk(t) if isinstance(n, ast.Name)]


def test_no_module_writes_a_command_or_message_id_as_a_number() -> None:
    bad = []
    for path in sorted(MAVLINK_SRC):
        tree = ast.parse(path.read_text(encoding="utf-8"))
        for node in tree.body:
            if isinstance(node, (ast.Assign, ast.AnnAssign)) and node.value is not None:
                names = [n for n in _targets(node) if n.startswith(ID_PREFIXES) or n in ID_TABLES]
                if names and any(_int_literals(part) for part in _id_parts(node.value)):
                    bad.append(f"{path.name}:{node.lineno} {', '.join(names)}")
        for node in ast.walk(tree):  # `cmd.command in (521, ...)`
            if (isinstance(node, ast.Compare) and "command" in ast.unparse(node.left).lower()
                    and any(_int_literals(c) for c in node.comparators)):  # fmt: skip
                bad.append(f"{path.name}:{node.lineno} {ast.unparse(node)}")
    assert not bad, "MAVLink ids written as numbers (use links.mav's mav_id / msg_id):\n" + "\n".join(bad)


def test_every_named_id_is_pymavlinks() -> None:
    """Each module's CMD_* is a MAV_CMD value and each MSG_* a message id pymavlink knows, under
    the name the constant says (spot checks against the spec's numbers)."""
    commands = set(ml.enums["MAV_CMD"])
    messages = set(ml.mavlink_map)
    seen = 0
    for path in sorted(MAVLINK_SRC):
        mod = importlib.import_module(f"topgimbal.{path.parent.name}.{path.stem}")
        for name, value in vars(mod).items():
            if name.startswith(("CMD_", "MAV_CMD_")) and isinstance(value, int):
                assert value in commands, f"{path.name}: {name} = {value} is no MAV_CMD"
                seen += 1
            elif name.startswith("MSG_") and isinstance(value, int):
                assert value in messages, f"{path.name}: {name} = {value} is no message"
                seen += 1
    assert seen >= 30
    assert _mav.mav_id("MAV_CMD_REQUEST_MESSAGE") == 512
    assert _mav.msg_id("CAMERA_INFORMATION") == 259
    assert _mav.msg_id("GIMBAL_DEVICE_ATTITUDE_STATUS") == 285


def test_legacy_requests_map_each_command_to_its_message() -> None:
    from topgimbal.mavlink.services import LEGACY_REQUESTS, LEGACY_YES_NO

    names = {
        cmd: (ml.enums["MAV_CMD"][cmd].name, ml.mavlink_map[msg].msgname) for cmd, (msg, _) in LEGACY_REQUESTS.items()
    }
    assert names[ml.MAV_CMD_REQUEST_CAMERA_INFORMATION] == ("MAV_CMD_REQUEST_CAMERA_INFORMATION", "CAMERA_INFORMATION")
    assert names[ml.MAV_CMD_REQUEST_CAMERA_IMAGE_CAPTURE][1] == "CAMERA_IMAGE_CAPTURED"
    assert {521, 522, 525, 527} == LEGACY_YES_NO  # param1 0 = "do not send" (the spec's numbers)
