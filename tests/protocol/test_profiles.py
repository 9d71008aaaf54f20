"""Model profiles and catalog metadata: roles, groups, state keys, factory values, signs per kind of
quantity, and the per-model facts from public reports (issues 10 and 16)."""

from __future__ import annotations

import dataclasses
import re

import pytest

from topgimbal.errors import FieldValueError, UnsupportedError
from topgimbal.protocol import GROUPS, QUIRKS, ROLES, DeviceModel, Endpoint, factory_values, get_dialect, get_model
from topgimbal.protocol import models as models_module
from topgimbal.protocol.catalog import stored_form
from topgimbal.protocol.dialects import DIALECT_NAMES, all_models
from topgimbal.protocol.signs import flip, resolve_signs

pytestmark = pytest.mark.virtual

DIALECTS = [get_dialect(n) for n in DIALECT_NAMES]
SKY, TOP = get_dialect("skydroid"), get_dialect("topotek")


def test_every_command_has_a_known_role_and_group() -> None:
    for d in DIALECTS:
        for spec in d.commands.values():
            assert spec.role in ROLES and spec.group in GROUPS, (d.name, spec.ident)


def test_roles_find_commands_without_naming_a_dialect() -> None:
    found = {
        (d.name, role): getattr(d.by_role(role), "ident", None)
        for d in DIALECTS
        for role in ("version", "model_name", "hardware_version", "sd_capacity", "attitude", "palette", "range")
    }
    assert found == {
        ("skydroid", "version"): "VER", ("topotek", "version"): "VSN",
        ("skydroid", "model_name"): "MOD", ("topotek", "model_name"): "PA2",
        ("skydroid", "hardware_version"): "HWV", ("topotek", "hardware_version"): None,
        ("skydroid", "sd_capacity"): "SDC", ("topotek", "sd_capacity"): "SDC",
        ("skydroid", "attitude"): "GAC", ("topotek", "attitude"): "GAC",
        ("skydroid", "palette"): "IMG", ("topotek", "palette"): "IMG",
        ("skydroid", "range"): "SLR", ("topotek", "range"): "LRF",
    }  # fmt: skip
    assert SKY.by_role("sd_capacity", "C20") is None and SKY.by_role("attitude", "C13") is None
    assert SKY.by_role("range", "C13") is not None and SKY.by_role("range", "C12") is None
    with pytest.raises(UnsupportedError, match="the C20 has no sd_capacity command"):
        SKY.require_role("sd_capacity", "C20")
    rates = {c.ident: c.axes for c in TOP.commands_with_role("rate")}
    assert rates["YPR"] == ("yaw", "pitch", "roll") and rates["GSP"] == ("pitch",)
    with pytest.raises(KeyError, match="not a role"):
        SKY.by_role("selfie")


def test_state_keys_name_the_same_thing_in_both_dialects() -> None:
    for d in DIALECTS:
        assert d.require_role("attitude").state_keys == {
            "yaw_deg": "attitude.yaw_deg", "pitch_deg": "attitude.pitch_deg", "roll_deg": "attitude.roll_deg",
        }  # fmt: skip
        assert d.require_role("version").state_keys == {"version": "version"}
        assert d.require_role("model_name").state_keys == {"model": "model_name"}
        assert d.require_role("recording").state_keys == {"state": "recording"}
    assert "state_keys" in SKY.command("SDC").describe()


def test_factory_values_are_catalog_data_and_valid() -> None:
    assert factory_values(SKY.command("VOM"))["fps"] == 30 and factory_values(SKY.command("IQE"))["hue"] == 128
    assert factory_values(TOP.command("BIT")) == {"bitrate_kbps": 4000}
    assert factory_values(SKY.command("TAS")) == {"interval_s": 10}
    assert factory_values(TOP.command("IMG")) == {"palette": "white_hot"}
    assert factory_values(SKY.command("VID"))["primary"] == "1080p"
    for d in DIALECTS:  # every stored setting's factory state is a value its own codec accepts
        for spec in d.commands.values():
            form = stored_form(spec)
            if form is not None and form.fields:
                form.encode(factory_values(spec), spec.ident)


def test_vendor_terms_are_kept_apart_from_english_labels() -> None:
    cjk = re.compile(r"[\u3000-\u9fff]")
    for d in DIALECTS:
        for spec in d.commands.values():
            assert "§" not in spec.title, spec.ident
            for form in spec.forms:
                assert "§" not in form.title
                for f in form.fields:
                    assert "§" not in f.description, (spec.ident, f.name)
                    values = f.codec.describe().get("values") or f.codec.describe().get("tokens") or []
                    for v in values:
                        assert not cjk.search(v["label"]), (spec.ident, v)
    white = SKY.command("IMG").forms[0].fields[0].codec.describe()["values"][0]
    assert (white["label"], white["vendor_term"]) == ("White hot", "白热")


def test_signs_differ_per_kind_of_quantity() -> None:
    _, c12 = get_model("C12")
    s = resolve_signs(c12)
    assert (s["rate.yaw"], s["angle.yaw"], s["attitude.yaw"]) == (-1, 1, 1)  # GAY raw sign opposite to GSY
    assert flip(SKY.command("GSY"), {"yaw_rate_deg_s": 5.0}, s) == {"yaw_rate_deg_s": -5.0}
    assert flip(SKY.command("GAY"), {"yaw_deg": 5.0}, s) == {"yaw_deg": 5.0}
    assert flip(SKY.command("GSM"), {"yaw_rate_deg_s": 1.0, "pitch_rate_deg_s": 2.0}, s) == {
        "yaw_rate_deg_s": -1.0, "pitch_rate_deg_s": 2.0,
    }  # fmt: skip
    for name in ("C11", "C13"):
        assert resolve_signs(get_model(name)[1])["rate.yaw"] == -1  # GSY yaw inverted
    sip = resolve_signs(get_model("SIP")[1])
    assert all(sip[f"{k}.pitch"] == -1 for k in ("angle", "rate", "attitude"))  # TOPOTEK pitch down-positive
    # A user's axis override covers every kind (the model's kind entries too); a kind override one kind.
    assert resolve_signs(c12, {"yaw": 1})["rate.yaw"] == 1
    assert resolve_signs(c12, {"yaw": -1, "angle.yaw": 1})["angle.yaw"] == 1
    assert flip(SKY.command("GSY"), {"yaw_rate_deg_s": 5.0}, {"yaw": -1}) == {"yaw_rate_deg_s": -5.0}  # plain table
    for bad in ({"rate.tilt": -1}, {"speed.yaw": -1}, {"yaw": 0}, {"yaw": True}):
        with pytest.raises(FieldValueError):
            resolve_signs(c12, bad)


def test_c11_profile_from_public_reports() -> None:
    d, c11 = get_model("C11")
    assert d.name == "skydroid" and d.options["speed_unit_deg_s"] == 0.5  # 0.5 deg/s per step, +-127
    assert d.encode("GSY", yaw_rate_deg_s=-63.5).data == b"81" and c11.max_rate_deg_s == 63.5
    assert d.encode("DZM", zoom="zoom_in").dst == "M" and SKY.encode("DZM", zoom="zoom_in").dst == "D"
    assert c11.ignored == {"GAM", "GSM", "GAY", "GAP"} and all(d.supports(c11, i) for i in c11.ignored)
    assert not d.supports(c11, "GAR") and not d.supports(c11, "GSR") and c11.roll_range_deg == (0.0, 0.0)
    assert c11.stream_rates_hz == {"GAA": 50.0} and c11.host_feeds == {"FAI": 10.0, "TIM": 1.0}
    assert (
        c11.host_setup == (("FAE", {"state": "on"}),)
        and d.command("PTZ").forms[0].fields[0].codec.lookup("center").raw == "05"
    )  # type: ignore[union-attr]
    assert [e.kind for e in c11.endpoints] == ["udp"] and c11.host_address == "U"
    for spec in d.supported(c11):  # every request it can send fits the firmware's 28-byte frames
        for form in spec.forms_for("w", "request") + spec.forms_for("r", "request"):
            assert 12 + form.max_length <= c11.max_frame_bytes, (spec.ident, form.title)  # type: ignore[operator]
    assert c11.quirks["needs_video_output"] and c11.quirks["no_clock"]


@pytest.mark.loopback
def test_c12_c13_and_sip_profile_facts() -> None:
    _, c12 = get_model("C12")
    assert [(e.kind, e.port) for e in c12.alternate_endpoints] == [("udp", 12580)]
    assert "assistant app" in c12.endpoints[0].note and c12.min_command_gap_s == 0.04
    assert c12.pitch_range_deg == (-45.0, 45.0) and c12.slow_answers == {"MOD"}
    with pytest.raises(FieldValueError, match=r"-45\.\.45 on the C12"):
        SKY.check_values(c12, "GAP", {"pitch_deg": -60})
    _, c13 = get_model("C13")
    assert c13.no_echo >= {"GAY", "GSY", "PTZ"} and c13.stop_repeats > 1 and c13.gimbal_header == "#TP"
    assert SKY.encode("GAM", yaw_deg=1, pitch_deg=1).header == "#TP"  # long G-class frames keep #TP
    top, sip = get_model("SIP")
    assert top.require_role("model_name", sip).ident == "PA2" and sip.identity["version"] in ("1.2.3", "123")
    assert sip.stream_rates_hz == {"GAA": 10.0, "GIA": 10.0}
    assert sip.video[0].url_for("127.0.0.1") == "rtsp://127.0.0.1:554/stream=0"


def test_identity_strings_reported_by_each_model() -> None:
    versions = {name: m.identity.get("version") for name, m in all_models().items()}
    documented = {
        "C10": "V1.2.0", "C10Pro": "V1.2.0", "C11": "V1.0.78", "C12": "010502", "C13": "V1.1.0", "C20": "V1.0.3",
        "SIP": "1.2.3",
    }  # fmt: skip
    assert {name: versions.get(name) for name in documented} == documented  # what each source reports
    for m in all_models().values():  # every model, a new one too
        assert m.identity["model_name"] == m.name and set(m.quirks) <= set(QUIRKS)
        assert isinstance(m.identity.get("version"), str) and m.identity["version"], m.name


def test_users_override_a_profile_per_device() -> None:
    d, c12 = get_model("C12")
    mine = dataclasses.replace(c12, commands=(c12.commands or frozenset()) | {"SLR"}, wire_signs={})
    assert d.supports(mine, "SLR") and not d.supports(c12, "SLR") and not d.supports("C12", "SLR")
    assert get_model(mine) == (d, mine) and resolve_signs(mine)["rate.yaw"] == 1
    c11_like = dataclasses.replace(c12, name="C12-lab", destinations={"DZM": "M"})
    assert get_model(c11_like)[0].command("DZM").address == "M"


@pytest.mark.parametrize(
    ("changes", "message"),
    [
        ({"wire_signs": {"tilt": -1}}, "wire_signs"),
        ({"quirks": {"sneezes": True}}, "unknown quirk"),
        ({"host_address": "G"}, "host_address"),
        ({"max_frame_bytes": 5}, "smallest frame"),
        ({"commands": frozenset({"GAY"}), "ignored": frozenset({"GSY"})}, "not in its commands"),
        ({"destinations": {"DZM": "X"}}, "destination"),
    ],
)
def test_profiles_are_validated(changes: dict[str, object], message: str) -> None:
    with pytest.raises(ValueError, match=message):
        DeviceModel(name="X", dialect="skydroid", title="x", endpoints=(), **changes)  # type: ignore[arg-type]
    with pytest.raises(ValueError, match="port"):
        Endpoint("udp", 70000)


def test_every_profile_field_is_documented() -> None:
    doc = models_module.__doc__ or ""
    for f in dataclasses.fields(DeviceModel):
        assert f.name.split("_range_deg")[0] in doc, f.name
