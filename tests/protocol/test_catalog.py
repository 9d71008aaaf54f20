"""The catalog as data: invariants, and a round trip of every form of every command."""

from __future__ import annotations

import itertools
import re

import pytest

from topgimbal.errors import FieldValueError, UnknownCommandError, UnsupportedError
from topgimbal.protocol import RESPONSE, get_dialect, get_model, make_frame
from topgimbal.protocol.dialects import DIALECT_NAMES, PROFILES, all_models

pytestmark = pytest.mark.virtual

DIALECTS = [get_dialect(n) for n in DIALECT_NAMES]
# The round trip of every form of every command: test_roundtrip_properties.py (hypothesis, values
# generated from each codec's metadata, edges and half steps included).

# Every identifier either document defines (collected by hand from the two documents' sections and
# appendices) must be in that dialect's catalog.
SKYDROID_IDS = [
    "PTZ",
    "GSY",
    "GSP",
    "GSR",
    "GSM",
    "GAY",
    "GAP",
    "GAR",
    "GAM",
    "GAA",
    "GAC",
    "SUM",
    "GOT",
    "FAE",
    "FAI",
    "REC",
    "CAP",
    "VID",
    "SDC",
    "AWB",
    "IQE",
    "TIM",
    "DZM",
    "IMG",
    "IPV",
    "GTW",
    "DNS",
    "BNS",
    "VOM",
    "VER",
    "EXT",
    "UID",
    "TSM",
    "TAS",
    "TDI",
    "TIB",
    "TIC",
    "TAR",
    "TTR",
    "TGM",
    "SLR",
    "ZMC",
    "FCC",
    "ZFP",
    "IRC",
    "MNU",
    "EVS",
    "LAT",
    "LON",
    "ALT",
    "TMP",
    "RST",
    "RTF",
    "ERE",
]
TOPOTEK_IDS = [
    "ZMC",
    "ZOM",
    "FCC",
    "FOC",
    "ZFP",
    "ZMP",
    "SWH",
    "IRC",
    "ATE",
    "VSN",
    "MUL",
    "APC",
    "PTZ",
    "GSY",
    "GSP",
    "GSR",
    "GSM",
    "RPS",
    "YPR",
    "GAY",
    "GAP",
    "GAR",
    "GAM",
    "GIY",
    "GIP",
    "GIR",
    "GIM",
    "GAC",
    "GAA",
    "GIC",
    "GIA",
    "GMS",
    "VER",
    "REC",
    "CAP",
    "VID",
    "BIT",
    "SDC",
    "ROT",
    "IPV",
    "GTW",
    "RST",
    "LON",
    "LAT",
    "ALT",
    "AZI",
    "GPS",
    "UAV",
    "LRF",
    "TIM",
    "UTC",
    "PIP",
    "TMP",
    "TMR",
    "IMG",
    "DZM",
    "DFG",
    "ENT",
    "ERE",
]
BEYOND_IDS = ["YPR", "GIA", "PA2", "TRC", "LOC", "LRF"]


def test_every_documented_identifier_is_in_its_catalog() -> None:
    assert set(SKYDROID_IDS) <= set(get_dialect("skydroid").commands)
    assert set(TOPOTEK_IDS) <= set(get_dialect("topotek").commands)
    assert set(BEYOND_IDS) <= set(get_dialect("topotek").commands)


def test_identifiers_and_names_are_well_formed_and_unique() -> None:
    for d in DIALECTS:
        names = [s.name for s in d.commands.values()]
        assert len(names) == len(set(names)), d.name
        for spec in d.commands.values():
            assert re.fullmatch(r"[A-Z0-9]{3}", spec.ident)
            assert re.fullmatch(r"[a-z][a-z0-9_]*", spec.name)
            assert spec.address in "MDEGU"
            assert spec.section
            assert spec.forms, spec.ident


def test_every_field_name_carries_its_unit() -> None:
    suffix = {
        "deg": "_deg",
        "deg/s": "_deg_s",
        "m": "_m",
        "MB": "_mb",
        "m/s": "_m_s",
        "degC": "_c",
        "s": "_s",
        "Hz": "_hz",
        "kbps": "_kbps",
        "x": "_x",
        "px": "_px",
    }
    for d in DIALECTS:
        for spec in d.commands.values():
            for form in spec.forms:
                for f in form.fields:
                    if f.unit in suffix:
                        assert f.name.endswith(suffix[f.unit]), (d.name, spec.ident, f.name, f.unit)


def test_attitude_answers_name_yaw_pitch_roll_in_degrees() -> None:
    for d, ident in [
        ("skydroid", "GAC"),
        ("topotek", "GAC"),
        ("topotek", "GIC"),
        ("topotek", "GIA"),
        ("skydroid", "FAI"),
    ]:
        spec = get_dialect(d).command(ident)
        names = [[f.name for f in form.fields][:3] for form in spec.forms if len(form.fields) >= 3]
        assert names and all(n == ["yaw_deg", "pitch_deg", "roll_deg"] for n in names), (d, ident)


def test_models_and_support_sets() -> None:
    profiles = {m.name for models in PROFILES.values() for m in models}
    assert set(all_models()) == profiles  # every profile, each as its own dialect holds it
    assert profiles >= {"C10", "C10Pro", "C11", "C12", "C13", "C20", "SIP"}  # the documents' models
    sky = get_dialect("skydroid")
    assert sky.supports("C12", "GOT") and not sky.supports("C10", "GOT")
    assert sky.supports("C13", "SLR") and not sky.supports("C12", "SLR")
    assert not sky.supports("C20", "REC") and sky.supports("C20", "PTZ")
    _, c12 = get_model("c12")
    assert c12.endpoints[0].kind == "udp" and c12.endpoints[0].port == 5000
    _, c10 = get_model("C10")
    assert [(e.kind, e.port) for e in c10.endpoints] == [("udp", 5000), ("tcp", 5000), ("udp", 9002)]
    d, sip = get_model("SIP")
    assert d.name == "topotek" and sip.yaw_range_deg == (-150.0, 150.0) and sip.wire_signs["pitch"] == -1
    with pytest.raises(UnknownCommandError, match="C99"):
        get_model("C99")


def test_model_limits_and_support_are_checked() -> None:
    sky = get_dialect("skydroid")
    _, c12 = get_model("C12")
    _, c13 = get_model("C13")
    _, c20 = get_model("C20")
    sky.check_values(c12, "TAS", {"interval_s": 25})
    with pytest.raises(FieldValueError, match=r"interval_s=30.*0\.\.25 on the C12"):
        sky.check_values(c12, "TAS", {"interval_s": 30})
    with pytest.raises(FieldValueError, match=r"5\.\.100 on the C13"):
        sky.check_values(c13, "TAS", {"interval_s": 2})
    with pytest.raises(UnsupportedError, match="C20 does not support CAP"):
        sky.check_values(c20, "CAP", {})


def test_same_identifier_means_different_things_per_dialect() -> None:
    sky, top = get_dialect("skydroid"), get_dialect("topotek")
    assert sky.decode(make_frame("PTZ", "06", dst="G")).fields == {"action": "follow"}
    assert top.decode(make_frame("PTZ", "06", dst="G")).fields == {"action": "lock"}
    assert sky.encode("GSY", yaw_rate_deg_s=-3.0).data == b"E2"  # 0.1 deg/s steps (errata E7)
    assert top.encode("GSY", yaw_rate_deg_s=-30).data == b"E2"  # 1 deg/s steps (errata E8)
    assert get_dialect("skydroid", speed_unit_deg_s=0.5).encode("GSY", yaw_rate_deg_s=-15).data == b"E2"
    with pytest.raises(FieldValueError, match="yaw_deg=120"):
        sky.encode("GAY", yaw_deg=120)
    assert top.encode("GAY", yaw_deg=120).data[:4] == b"2EE0"


def test_dialects_are_independent_objects() -> None:
    a = get_dialect("skydroid", speed_unit_deg_s=0.5)
    b = get_dialect("skydroid")
    assert a is not b and b.options["speed_unit_deg_s"] == 0.1 and a.options["speed_unit_deg_s"] == 0.5
    assert get_dialect("skydroid") is b  # the default one is shared (immutable)
    with pytest.raises(UnknownCommandError, match="dialect"):
        get_dialect("mavlink")


def test_typed_encode_and_response_helpers() -> None:
    sky = get_dialect("skydroid")
    req = sky.encode("GAC", read=True)
    assert req.to_bytes() == b"#TPUG2rGAC0032"
    ans = sky.response(req, yaw_deg=-50, pitch_deg=12.34, roll_deg=0)
    assert (ans.src, ans.dst, ans.rw, ans.header) == ("G", "U", "r", "#TP")
    assert sky.decode(ans).fields == {"yaw_deg": -50.0, "pitch_deg": 12.34, "roll_deg": 0.0}
    top = get_dialect("topotek")
    note = top.notification("LRF", src="E", dst="P", distance_m=123.4)
    assert note.data == b"00123.4" and top.decode(note).fields == {"distance_m": 123.4}
    err = top.notification("LRF", src="E", dst="P", distance_m=None)
    assert err.data == b"ERR" and top.decode(err).fields == {"distance_m": None}
    rec = top.response(top.encode("REC", action="start", src="P"), state="started", file_index=0x1F)
    assert rec.data == b"110000001F" and rec.dst == "P"


def test_encode_errors_name_field_value_and_allowed() -> None:
    sky = get_dialect("skydroid")
    with pytest.raises(FieldValueError) as exc:
        sky.encode("PTZ", action="spin")
    assert "action='spin'" in str(exc.value) and "follow (06)" in str(exc.value)
    with pytest.raises(FieldValueError, match=r"colour.*a field of PTZ.*action"):
        sky.encode("PTZ", colour=1)
    with pytest.raises(FieldValueError, match="requires it"):
        sky.encode("GOT", x_px=10)
    with pytest.raises(UnsupportedError, match="cannot be read"):
        sky.encode("PTZ", read=True)
    with pytest.raises(UnknownCommandError, match="'XYZ' is not a command of the skydroid dialect"):
        sky.encode("XYZ")
    with pytest.raises(FieldValueError, match="address"):
        sky.encode("IPV", address="300.1.2.3")
    with pytest.raises(FieldValueError, match="yaw_deg=nan"):
        sky.encode("GAY", yaw_deg=float("nan"))
    with pytest.raises(FieldValueError, match="yaw_deg=True"):
        sky.encode("GAY", yaw_deg=True)


def test_decode_never_raises_and_says_why() -> None:
    sky = get_dialect("skydroid")
    unknown = sky.decode(make_frame("QQQ", "00"))
    assert unknown.fields is None and "not in the skydroid catalog" in (unknown.error or "")
    short = sky.decode(make_frame("GAY", "EF", dst="G"))
    assert short.fields is None and "2 data bytes" in (short.error or "")
    junk = sky.decode(make_frame("GAY", "XYZ123", dst="G"))
    assert junk.fields is None and "hex" in (junk.error or "")


def test_idempotency_follows_the_value_tables() -> None:
    sky, top = get_dialect("skydroid"), get_dialect("topotek")
    cases = [
        (sky, "REC", {"action": "toggle"}, False),
        (sky, "REC", {"action": "start"}, True),
        (sky, "DZM", {"zoom": "zoom_in"}, False),
        (sky, "DZM", {"zoom": "2x"}, True),
        (sky, "PTZ", {"action": "toggle_follow_lock"}, False),
        (sky, "PTZ", {"action": "center"}, True),
        (sky, "PTZ", {"action": "up"}, False),
        (sky, "CAP", {}, False),
        (sky, "GAY", {"yaw_deg": 3}, True),
        (top, "DZM", {"zoom": "step_in"}, False),
        (top, "DZM", {"zoom": 2.5}, True),
        (top, "IMG", {"palette": "next"}, False),
        (top, "IMG", {"palette": "lava"}, True),
    ]
    for d, ident, values, expected in cases:
        frame = d.encode(ident, **values)
        assert d.command(ident).is_idempotent(frame) is expected, (d.name, ident, values)
    assert sky.command("REC").is_idempotent(sky.encode("REC", read=True))


def test_header_rules() -> None:
    sky, top = get_dialect("skydroid"), get_dialect("topotek")
    assert sky.encode("GAY", yaw_deg=1).header == "#TP"  # every G-class frame (errata E1)
    assert sky.encode("IPV", read=True).header == "#tp"  # as the document writes it
    assert sky.encode("REC", action="start").header == "#TP"
    assert top.encode("YPR", yaw_rate_deg_s=1, pitch_rate_deg_s=2, roll_rate_deg_s=3).header == "#tp"
    tmp22 = top.notification(
        "TMP",
        src="D",
        dst="P",
        hot_x_px=1,
        hot_y_px=2,
        hot_temp_c=3.5,
        cold_x_px=4,
        cold_y_px=5,
        cold_temp_c=-1.5,
        center_temp_c=20.0,
    )
    assert tmp22.header == "#tP" and len(tmp22.data) == 22 and tmp22.to_bytes()[5] == 22


def test_all_forms_have_consistent_lengths() -> None:
    for d in DIALECTS:
        for spec, _form in itertools.product(d.commands.values(), [None]):
            for f in spec.forms:
                assert 0 <= f.min_length <= f.max_length, (spec.ident, f)
                if f.direction == RESPONSE and spec.header in ("#TP", "#tp"):
                    assert f.min_length <= 15, spec.ident


def test_notification_never_picks_an_echo_form() -> None:
    """LAT has an echo (ddmm.mmmm) and a target-solution report (dd.dddddd) with the same field."""
    top = get_dialect("topotek")
    note = top.notification("LAT", src="D", dst="P", lat_deg=22.123456)
    assert note.data == b"N22.123456"
    assert top.decode(note).form.title == "target solution"  # type: ignore[union-attr]
    echo = top.encode("LAT", lat_deg=22.5).swapped()
    assert top.decode(echo).fields == {"lat_deg": 22.5} and top.decode(echo).form.role == "echo"  # type: ignore[union-attr]


def test_sign_metadata_is_in_the_catalog() -> None:
    """Which fields carry a gimbal axis (model wire signs apply) or a fixed documented sign."""
    from topgimbal.protocol.signs import flip, resolve_signs

    top, sip = get_model("SIP")
    signs = resolve_signs(sip)
    assert flip(top.command("GIP"), {"pitch_deg": 30, "speed_deg_s": 5}, signs) == {"pitch_deg": -30, "speed_deg_s": 5}
    assert flip(top.command("GAM"), {"yaw_speed_deg_s": 5, "pitch_speed_deg_s": 5}, signs)["pitch_speed_deg_s"] == 5
    assert flip(top.command("GIA"), {"yaw_deg": 1, "pitch_deg": 2, "roll_deg": 3}, signs) == {
        "yaw_deg": 1, "pitch_deg": -2, "roll_deg": 3,
    }  # fmt: skip
    # UAV pitch is down-positive by its own document, whatever the model's gimbal convention
    for override in ({}, {"pitch": 1}):
        s = resolve_signs(sip, override)
        assert flip(top.command("UAV"), {"pitch_deg": 5, "roll_deg": 2}, s) == {"pitch_deg": -5, "roll_deg": 2}
    sky, c12 = get_model("C12")
    assert flip(sky.command("FAI"), {"pitch_deg": 5}, resolve_signs(c12, {"pitch": -1})) == {"pitch_deg": 5}
    assert flip(sky.command("GSP"), {"pitch_rate_deg_s": 5}, resolve_signs(c12, {"pitch": -1})) == {
        "pitch_rate_deg_s": -5
    }
    with pytest.raises(FieldValueError, match="an axis name"):
        resolve_signs(c12, {"tilt": -1})
    motion = {c.ident for c in top.commands.values() if c.motion}
    assert motion == set(
        ["PTZ", "GSY", "GSP", "GSR", "GSM", "RPS", "YPR", "GAY", "GAP", "GAR", "GAM", "GIY", "GIP", "GIR", "GIM"]
    )


def test_commands_describe_themselves_as_json() -> None:
    import json

    d = get_dialect("skydroid").command("GAY").describe()
    json.dumps(d)  # JSON-able as is
    assert d["id"] == "GAY" and d["motion"] is True
    assert d["models"] is None  # every SkyDroid model (C11, C13: public reports, errata E27, E28)
    gar = get_dialect("skydroid").command("GAR").describe()["models"]  # roll: not the C11 (no roll) nor the C13
    assert {"C10", "C10Pro", "C12", "C20"} <= set(gar) and not {"C11", "C13"} & set(gar), gar
    yaw = d["forms"][0]["fields"][0]
    assert (yaw["name"], yaw["min"], yaw["max"], yaw["step"], yaw["unit"], yaw["axis"]) == (
        "yaw_deg", -90, 90, 0.01, "deg", "yaw",
    )  # fmt: skip
    assert get_dialect("skydroid").command("AWB").describe()["models"] is None  # every model
    q = get_dialect("topotek").command("SDC").describe()["forms"]
    assert [f["const"] for f in q if f["rw"] == "r" and f["direction"] == "request"] == [None]
