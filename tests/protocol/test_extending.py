"""docs/architecture.md "How to add a command" and "How to add a model", done here with a toy: the
same public building blocks the dialect tables and profiles use (Field and codecs, Form,
CommandSpec, DeviceModel, Dialect), checked for encode, decode, support, roles, signs, factory values
and the generated reference page."""

from __future__ import annotations

import pytest

from topgimbal.protocol import (
    QUERY,
    REQUEST,
    RESPONSE,
    CommandSpec,
    DeviceModel,
    Dialect,
    Endpoint,
    Field,
    Form,
    factory_values,
)
from topgimbal.protocol.dialects import skydroid_models
from topgimbal.protocol.dialects.skydroid import commands as skydroid_commands
from topgimbal.protocol.fields import HexInt, enum
from topgimbal.protocol.signs import flip, resolve_signs
from topgimbal.tools.gendocs import render

pytestmark = pytest.mark.virtual

# Step 1 of "How to add a command": a row (here built without the tables' `command()` shorthand).
SPEED = Field("speed_pct", HexInt(2, max=100, unit="%"), "fan speed", factory=50, state_key="fan.speed_pct")
MODE = Field("mode", enum(1, {"0": "auto", "1": ("manual", "Manual", "手动")}), factory="auto")
FAN = CommandSpec(
    ident="FAN",
    name="fan",
    title="Cooling fan",
    address="D",
    forms=(
        Form("w", REQUEST, (MODE, SPEED), title="set / control"),
        Form("w", RESPONSE, (MODE, SPEED), title="echo", role="echo"),
        QUERY,
        Form("r", RESPONSE, (MODE, SPEED), title="answer"),
    ),
    section="toy document §1",
    role="aux_power",
    group="system",
)

# "How to add a model": one profile row; its `commands` set says what it supports.
TOY = DeviceModel(
    name="T1",
    dialect="skydroid",
    title="Toy gimbal T1",
    endpoints=(Endpoint("udp", 5600),),
    commands=skydroid_models.COMMON | {"FAN", "GAY", "GAC", "GAA"},
    pitch_range_deg=(-30.0, 30.0),
    wire_signs={"angle.yaw": -1},
    limits={("FAN", "speed_pct"): (20.0, 80.0)},
    identity={"version": "T0.1", "model_name": "T1"},
    quirks={"crlf": True},
)


def toy_dialect() -> Dialect:
    return Dialect(
        "skydroid",
        "SkyDroid with a toy fan",
        [*skydroid_commands(0.1), FAN],
        [*skydroid_models.MODELS, TOY],
        gimbal_header="#TP",
    )


def test_a_toy_command_encodes_decodes_and_is_supported_by_its_model_only() -> None:
    d = toy_dialect()
    frame = d.encode("FAN", mode="manual", speed_pct=40)
    assert frame.to_bytes() == b"#tpUD3wFAN128" + b"%02X" % (sum(b"#tpUD3wFAN128") & 0xFF)
    assert d.decode(frame.swapped()).fields == {"mode": "manual", "speed_pct": 40}
    assert d.decode(d.encode("FAN", read=True)).form is QUERY
    assert d.supports(TOY, "FAN") and d.supports("T1", "FAN") and not d.supports("C12", "FAN")
    assert d.command("FAN").models == frozenset({"T1"}) and d.by_role("aux_power", "T1") is d.command("FAN")
    assert factory_values(d.command("FAN")) == {"mode": "auto", "speed_pct": 50}
    assert d.command("FAN").state_keys == {"speed_pct": "fan.speed_pct"}
    d.check_values(TOY, "FAN", {"speed_pct": 40})
    try:
        d.check_values(TOY, "FAN", {"speed_pct": 90})
    except ValueError as exc:
        assert "20..80 on the T1" in str(exc)
    else:
        raise AssertionError("the T1's limit was not checked")


def test_a_toy_model_carries_its_signs_and_support() -> None:
    d = toy_dialect()
    assert d.model("t1") is TOY and not d.supports(TOY, "GSY") and d.supports(TOY, "GAY")
    signs = resolve_signs(TOY)
    assert flip(d.command("GAY"), {"yaw_deg": 10.0}, signs) == {"yaw_deg": -10.0}
    assert flip(d.command("GAC"), {"yaw_deg": 10.0}, signs) == {"yaw_deg": 10.0}
    assert TOY.quirk_defaults()["crlf"] and not TOY.quirk_defaults()["lowercase_header"]


def test_the_reference_page_renders_the_toy() -> None:
    page = render([toy_dialect()])
    assert "| `FAN` | fan<br>Cooling fan | `aux_power` / system |" in page
    assert "| T1 | UDP 5600 | `U` | -90..90 / -30..30 / -90..90 |" in page and "angle.yaw -" in page
    assert "| `aux_power` |" in page and "`FAN`" in page.split("## Roles")[1]
