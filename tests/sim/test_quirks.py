"""Every quirk of `protocol.QUIRKS`, switched on and off: the device does what the quirk says only
while it is on. One test per quirk (the table at the end checks none is missing), plus the model
facts of issue 10 that are not switches (roll, centring, tilt range, model name)."""

from __future__ import annotations

from collections.abc import Callable
from datetime import datetime

import pytest

from topgimbal.protocol import QUIRKS, all_models, get_model, make_frame
from topgimbal.sim import quirks as quirk_table
from topgimbal.sim.device import Device

from .conftest import DeviceHarness, raw, req

pytestmark = pytest.mark.virtual


def harness(model: str, **quirks: bool | float | None) -> DeviceHarness:
    return DeviceHarness(model, quirk_overrides=quirks)


def idents(frames: list) -> list[str]:  # type: ignore[type-arg]
    return [f.ident for f in frames]


# -- one test per quirk ------------------------------------------------------------------------------


def lowercase_header(on: bool) -> None:
    h = harness("SIP", lowercase_header=on)
    [reply] = h.ask("GMS", read=True)  # two data characters: #TP by the document's rule
    assert reply.header == ("#tp" if on else "#TP")


def crlf(on: bool) -> None:
    h = harness("C12", crlf=on)
    [o] = h.dev.receive("p", req("C12", "GAC", read=True))
    assert o.data.endswith(b"\r\n") is on


def no_motion_echo(on: bool) -> None:
    h = harness("C13", no_motion_echo=on)  # C13: on by default, for the profile's no_echo set
    assert idents(h.ask("GSP", pitch_rate_deg_s=5.0)) == ([] if on else ["GSP"])
    h.advance(1.0)
    assert h.dev.gimbal.pitch_deg > 1.0  # obeyed either way
    assert idents(h.ask("IRC", mode="night")) == ["IRC"]  # not a motion command: echoed


def ver_wrong_length(on: bool) -> None:
    h = harness("C12", ver_wrong_length=on)
    [o] = h.dev.receive("p", req("C12", "VER", read=True))
    assert o.data == (b"#tpDU3rVER0105025A" if on else b"#tpDU6rVER0105025D")


def ignored_commands(on: bool) -> None:
    h = harness("C11", ignored_commands=on)
    out = h.ask("GAY", yaw_deg=40.0, speed_deg_s=9.9)
    h.advance(5.0)
    assert idents(out) == ([] if on else ["GAY"])
    assert h.dev.gimbal.yaw_deg == (0.0 if on else pytest.approx(40.0))
    assert idents(h.ask("GSP", pitch_rate_deg_s=5.0)) == ["GSP"]  # rates still work: the closed loop


def stop_coasts(on: bool) -> None:
    h = harness("C13", stop_coasts=on, no_motion_echo=False)
    h.ask("GSY", yaw_rate_deg_s=10.0)
    h.advance(1.0)
    h.ask("PTZ", action="stop")
    at_stop = h.dev.gimbal.yaw_deg
    h.advance(0.1)
    rate_after = h.dev.gimbal.yaw_axis.vel
    h.advance(2.0)
    coasted = h.dev.gimbal.yaw_deg - at_stop
    if on:
        assert abs(rate_after) == pytest.approx(10.0)  # still going a tenth of a second later
        assert 1.0 < abs(coasted) < 6.0 and h.dev.gimbal.yaw_axis.vel == 0.0  # then it stops by itself
    else:
        assert abs(rate_after) < 10.0 and abs(coasted) < 0.5  # decelerates at once
    # A repeated stop halts at once, whatever the quirk.
    h.ask("GSY", yaw_rate_deg_s=10.0)
    h.advance(1.0)
    h.ask("PTZ", action="stop")
    h.ask("PTZ", action="stop")
    at_stop = h.dev.gimbal.yaw_deg
    h.advance(2.0)
    assert abs(h.dev.gimbal.yaw_deg - at_stop) < 0.5


def late_answers(on: bool) -> None:
    h = harness("C12", late_answers=on)
    assert idents(h.ask("MOD", read=True)) == ([] if on else ["MOD"])
    assert idents(h.ask("GAC", read=True)) == ["GAC"]  # other requests are not held up
    later = h.advance(121.0)
    assert idents(later) == (["MOD"] if on else [])
    for value, wait, seen in ((30.0, 31.0, ["MOD"]), (None, 1000.0, [])):
        h = harness("C12", late_answers=value)
        assert h.ask("MOD", read=True) == [] and idents(h.advance(wait)) == seen


def needs_video_output(on: bool) -> None:
    h = harness("C11", needs_video_output=on)
    assert idents(h.ask("REC", action="start")) == ["REC"]  # acknowledged either way
    assert h.dev.camera.recording is not on
    h.dev.camera.video_output = True  # a video client started playing
    h.ask("REC", action="start")
    assert h.dev.camera.recording
    # A model with VOM: its output switch is what starts video output (factory: on).
    c12 = harness("C12", needs_video_output=on)
    c12.ask("VOM", h_flip="off", v_flip="off", fps=30, gop=30, bitrate_kbps=4000, output="off")
    c12.ask("IRC", mode="night")
    assert c12.dev.camera.day_night == ("day" if on else "night")
    c12.ask("VOM", h_flip="off", v_flip="off", fps=30, gop=30, bitrate_kbps=4000, output="on")
    c12.ask("IRC", mode="night")
    assert c12.dev.camera.day_night == "night"


def no_clock(on: bool) -> None:
    h = harness("C11", no_clock=on)
    h.advance(90.0)
    assert h.dev.camera_time() == (datetime(1970, 1, 1, 0, 1, 30) if on else None)
    h.ask("TIM", time=datetime(2025, 5, 29, 12, 0, 0))
    h.advance(2.0)
    assert h.dev.camera_time() == datetime(2025, 5, 29, 12, 0, 2)


def gimbal_header_required(on: bool) -> None:
    h = harness("C13", gimbal_header_required=on, no_motion_echo=False)
    lower = raw("GAP", "0BB863", dst="G", header="#tp")  # pitch 30, as a firmware ignored it
    assert idents(h.send(lower)) == ([] if on else ["GAP"])
    h.advance(10.0)
    assert h.dev.gimbal.pitch_deg == (0.0 if on else pytest.approx(30.0))
    h.send(raw("GAP", "F63C63", dst="G", header="#TP"))  # -25: the #TP spelling always works
    h.advance(10.0)
    assert h.dev.gimbal.pitch_deg == pytest.approx(-25.0)


def command_pacing(on: bool) -> None:
    h = harness("C12", command_pacing=on)
    assert idents(h.ask("GAC", read=True)) == ["GAC"]
    h.clock.advance(0.01)
    assert idents(h.ask("GAC", read=True)) == ([] if on else ["GAC"])  # 10 ms after: too soon
    h.clock.advance(0.05)
    assert idents(h.ask("GAC", read=True)) == ["GAC"]  # 50 ms after the last one taken: fine


def frame_size_limit(on: bool) -> None:
    h = harness("C11", frame_size_limit=on)
    long = make_frame("DZM", b"0" * 20, src="U", dst="M", header="#tP").to_bytes()  # 32 bytes
    assert idents(h.send(long)) == ([] if on else ["ERE"])  # too long / no form that long
    assert idents(h.ask("DZM", zoom="2x")) == ["DZM"]


def fixed_stream_rate(on: bool) -> None:
    h = harness("C11", fixed_stream_rate=on)
    h.ask("GAA", rate_hz=10)
    assert len(h.advance(1.0)) == (50 if on else 10)


def wire_signs(on: bool) -> None:
    h = harness("C12", wire_signs=on)
    h.ask("GSY", yaw_rate_deg_s=5.0)  # C12: GSY yaw inverted on the wire
    h.advance(1.0)
    assert (h.dev.gimbal.yaw_deg < 0) is on
    sip = harness("SIP", wire_signs=on)
    sip.ask("GIP", pitch_deg=20.0, speed_deg_s=9.9)  # SIP: pitch down-positive on the wire
    sip.advance(10.0)
    assert sip.dev.gimbal.pitch_deg == pytest.approx(-20.0 if on else 20.0)


def speed_unit(on: bool) -> None:
    h = harness("C11", speed_unit=on, wire_signs=False)
    h.send(raw("GSY", "14", dst="G"))  # 20 steps right: 10 deg/s (C11, 0.5 deg/s per step), else 2
    h.advance(2.0)
    h.send(raw("GSY", "00", dst="G"))
    h.advance(1.0)
    assert h.dev.gimbal.yaw_deg == pytest.approx(20.0 if on else 4.0, abs=1.5)


def strict_destinations(on: bool) -> None:
    h = harness("C11", strict_destinations=on)
    h.dev.camera.video_output = True
    assert idents(h.send(raw("DZM", "02", dst="D"))) == ([] if on else ["DZM"])  # the documented address
    assert idents(h.send(raw("DZM", "03", dst="M"))) == ["DZM"]  # where the C11 wants it
    assert h.dev.camera.digital_zoom_x == 3.0


def version_digits_only(on: bool) -> None:
    h = harness("SIP", version_digits_only=on)
    assert h.decode(h.ask("VSN", read=True)[0])["version"] == ("123" if on else "1.2.3")
    assert h.decode(h.send(raw("VSN", "00", src="P", dst="M", rw="r"))[0])["version"] == "M3326"


QUIRK_TESTS: dict[str, Callable[[bool], None]] = {
    f.__name__: f
    for f in (
        lowercase_header,
        crlf,
        no_motion_echo,
        ver_wrong_length,
        ignored_commands,
        stop_coasts,
        late_answers,
        needs_video_output,
        no_clock,
        gimbal_header_required,
        command_pacing,
        frame_size_limit,
        fixed_stream_rate,
        wire_signs,
        speed_unit,
        strict_destinations,
        version_digits_only,
    )
}


@pytest.mark.parametrize("on", [True, False], ids=["on", "off"])
@pytest.mark.parametrize("quirk", sorted(QUIRK_TESTS))
def test_quirk(quirk: str, on: bool) -> None:
    QUIRK_TESTS[quirk](on)


def test_every_quirk_has_its_test() -> None:
    assert set(QUIRK_TESTS) == set(QUIRKS)


# -- defaults, the CLI form, model facts that are not switches ----------------------------------------


@pytest.mark.parametrize("model", sorted(all_models()))
def test_defaults_come_from_the_profile(model: str) -> None:
    _, m = get_model(model)
    assert Device(model).quirks == {name: bool(m.quirks.get(name)) for name in QUIRKS}


def test_cli_form_and_values() -> None:
    assert quirk_table.parse("crlf,-ver_wrong_length,late_answers=30s,stop_coasts=off") == {
        "crlf": True,
        "ver_wrong_length": False,
        "late_answers": 30.0,
        "stop_coasts": False,
    }
    assert quirk_table.parse("late_answers=never") == {"late_answers": None}
    for bad, says in (("loud", "unknown quirk 'loud'"), ("crlf=30", "NAME=on/off"), ("late_answers=-2", "seconds")):
        with pytest.raises(ValueError, match=says):
            quirk_table.parse(bad)
    with pytest.raises(ValueError, match="late_answers"):
        Device("C12", quirk_overrides={"late_answers": "soon"})  # type: ignore[dict-item]


def test_c11_roll_cannot_be_commanded_and_ptz_05_centres() -> None:
    h = harness("C11")
    assert idents(h.send(raw("GSR", "10", dst="G"))) == ["ERE"]  # no roll commands on a C11
    h.ask("YPR" if "YPR" in h.dialect.commands else "GSP", pitch_rate_deg_s=10.0)
    h.advance(1.0)
    assert h.dev.gimbal.roll_deg == 0.0 and h.dev.gimbal.pitch_deg != 0.0
    assert idents(h.send(raw("PTZ", "05", dst="G"))) == ["PTZ"]
    h.advance(10.0)
    assert h.dev.gimbal.pitch_deg == 0.0


def test_c11_attitude_input_needs_fae_first() -> None:
    h = harness("C11")
    h.ask("FAI", yaw_deg=0.0, pitch_deg=5.0, roll_deg=0.0)
    assert h.dev.gimbal.vehicle.pitch == 0.0  # not yet switched on
    h.ask("FAE", state="on")
    h.ask("FAI", yaw_deg=0.0, pitch_deg=5.0, roll_deg=0.0, flight_mode="fixed_wing")
    assert h.dev.gimbal.vehicle.pitch == 5.0


def test_c12_tilt_is_limited_to_45_degrees() -> None:
    h = harness("C12")
    assert idents(h.ask("GSP", pitch_rate_deg_s=12.0)) == ["GSP"]
    h.advance(10.0)
    assert h.dev.gimbal.pitch_deg == 45.0  # the mechanical stop
    assert idents(h.send(raw("GAP", "1770" + "63", dst="G"))) == ["ERE"]  # 60 deg: beyond the profile's limit


def test_stop_coasting_is_the_same_for_the_same_seed() -> None:
    def coast(seed: int) -> float:
        h = DeviceHarness("C13", seed=seed)
        h.ask("GSY", yaw_rate_deg_s=10.0)
        h.advance(1.0)
        h.ask("PTZ", action="stop")
        h.advance(3.0)
        return h.dev.gimbal.yaw_deg

    assert coast(1) == coast(1) and coast(1) != coast(2)
