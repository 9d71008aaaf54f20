"""The sans-I/O device on a fake clock: echo / query / error rules, dialect differences, camera,
thermal, rangefinder, network, quirks."""

from __future__ import annotations

import pytest

from topgimbal.protocol import Frame, all_models, make_frame, parse_frame
from topgimbal.sim.device import Device
from topgimbal.sim.state import NetworkState

from .conftest import DeviceHarness, raw, req

pytestmark = pytest.mark.virtual

ERROR = "ERE"


def only(frames: list[Frame]) -> Frame:
    assert len(frames) == 1, frames
    return frames[0]


# -- the protocol's rules --------------------------------------------------------------------------


@pytest.mark.parametrize("model", sorted(all_models()))
def test_every_supported_query_is_answered_with_data_in_a_response_form(model: str) -> None:
    h = DeviceHarness(model)
    answered = 0
    for spec in h.dialect.supported(h.dev.model):
        form = next(iter(spec.forms_for("r", "request")), None)
        if form is None or (spec.ident == "TMP" and form.const is None):
            continue
        data = form.const if form.const is not None else form.encode({}, spec.ident)
        f = only(h.send(make_frame(spec.ident, data, src="U", dst=spec.address, rw="r").to_bytes()))
        if spec.ident in ("SLR",):  # out of range without an altitude: error frame
            assert f.ident == ERROR
            continue
        if spec.ident == "TMP" and not h.dev.model.thermal:
            assert f.ident == ERROR
            continue
        assert f.ident == spec.ident and f.rw == "r", f
        assert (f.src, f.dst) == (spec.address, "U")
        assert h.dialect.decode(f).fields is not None
        answered += 1
    assert answered >= 3


@pytest.mark.parametrize("model", ["C12", "SIP"])
def test_control_commands_are_echoed_with_swapped_addresses(model: str) -> None:
    h = DeviceHarness(model)
    request = req(model, "PTZ", action="center")
    reply = only(h.send(request))
    sent = parse_frame(request)
    assert reply.to_bytes() == sent.swapped().to_bytes()
    assert h.dev.received[-1] == sent


def test_unknown_malformed_and_unsupported_get_the_error_frame() -> None:
    h = DeviceHarness("C20")
    for data in (raw("ZZZ"), raw("PTZ", "7Z", dst="G"), raw("IMG", "01"), raw("GAC", "00", rw="w", dst="G")):
        f = only(h.send(data))
        sent = parse_frame(data)
        assert f.ident == ERROR and f.data == b"!!"
        assert (f.src, f.dst) == (sent.dst, sent.src)
        assert f.to_bytes() == make_frame("ERE", b"!!", src=sent.dst, dst=sent.src, header="#TP").to_bytes()


def test_bad_checksum_is_ignored_and_next_frame_still_answered() -> None:
    h = DeviceHarness("C12")
    good = req("C12", "GAC", read=True)
    bad = good[:-2] + (b"00" if good[-2:] != b"00" else b"01")
    assert h.send(bad) == []
    assert only(h.send(bad + good)).ident == "GAC"
    assert len(h.dev.received) == 1


def test_datagram_with_several_frames_and_crlf() -> None:
    h = DeviceHarness("C12")
    out = h.send(req("C12", "GAC", read=True) + b"\r\n" + req("C12", "REC", read=True) + b"\r\n")
    assert [f.ident for f in out] == ["GAC", "REC"]


def test_device_frames_sent_to_the_device_are_not_answered() -> None:
    h = DeviceHarness("C12")
    assert h.send(make_frame("GAC", "0000000000FF", src="G", dst="U", rw="r").to_bytes()) == []


# -- gimbal -----------------------------------------------------------------------------------------


def test_sip_pitch_is_down_positive_on_the_wire_for_angles_and_reports() -> None:
    h = DeviceHarness("SIP")
    h.ask("GIP", pitch_deg=30.0, speed_deg_s=9.9)  # wire +30 = 30 degrees down
    h.advance(10.0)
    assert h.dev.gimbal.pitch_deg == pytest.approx(-30.0)
    f = only(h.ask("GIC", read=True))
    assert h.decode(f)["pitch_deg"] == pytest.approx(30.0)


def test_skydroid_pitch_is_up_positive() -> None:
    h = DeviceHarness("C12")
    h.ask("GAP", pitch_deg=30.0, speed_deg_s=9.9)
    h.advance(10.0)
    assert h.dev.gimbal.pitch_deg == pytest.approx(30.0)
    assert h.decode(only(h.ask("GAC", read=True)))["pitch_deg"] == pytest.approx(30.0)


def test_speed_commands_in_each_dialects_units() -> None:
    sky = DeviceHarness("C10")  # documented signs (the C12's GSY yaw is inverted on the wire: errata E29)
    sky.ask("GSY", yaw_rate_deg_s=10.0)  # 100 steps of 0.1 deg/s
    sky.advance(2.0)
    assert 15.0 < sky.dev.gimbal.yaw_deg < 20.5
    top = DeviceHarness("SIP")
    top.ask("YPR", yaw_rate_deg_s=20.0, pitch_rate_deg_s=10.0, roll_rate_deg_s=0.0)  # pitch +10 on the wire = down
    top.advance(1.0)
    assert 15.0 < top.dev.gimbal.yaw_deg < 20.5
    assert -10.5 < top.dev.gimbal.pitch_deg < -7.0


def test_ptz_codes_per_dialect() -> None:
    sky, top = DeviceHarness("C12"), DeviceHarness("SIP")
    sky.send(raw("PTZ", "06", dst="G"))
    top.send(raw("PTZ", "06", dst="G", src="P"))
    assert (sky.dev.gimbal.mode, top.dev.gimbal.mode) == ("follow", "lock")
    sky.send(raw("PTZ", "08", dst="G"))
    assert sky.dev.gimbal.mode == "lock"
    sky.send(raw("PTZ", "0B", dst="G"))
    assert sky.dev.gimbal.mount == "inverted"
    sky.send(raw("PTZ", "0E", dst="G"))
    sky.send(raw("PTZ", "0E", dst="G"))
    assert sky.dev.gimbal.trims["x"] == pytest.approx(0.2)
    top.send(raw("PTZ", "0A", dst="G", src="P"))  # one-key look down
    top.advance(5.0)
    assert top.dev.gimbal.pitch_deg == pytest.approx(-90.0)
    top.send(raw("PTZ", "01", dst="G", src="P"))  # nudge up until stop
    top.advance(0.5)
    top.send(raw("PTZ", "00", dst="G", src="P"))
    top.advance(1.0)
    stopped = top.dev.gimbal.pitch_deg
    top.advance(1.0)
    assert -90.0 < stopped == top.dev.gimbal.pitch_deg


def test_gms_motor_off_and_query() -> None:
    h = DeviceHarness("SIP")
    h.ask("GMS", state="off")
    assert h.decode(only(h.ask("GMS", read=True)))["state"] == "off"
    h.ask("GAY", yaw_deg=40.0, speed_deg_s=9.9)
    h.advance(10)
    assert h.dev.gimbal.yaw_deg == 0.0


def test_uav_attitude_drives_earth_frame_hold() -> None:
    h = DeviceHarness("SIP")
    h.ask("GIP", pitch_deg=20.0, speed_deg_s=9.9)  # 20 down, earth frame
    h.ask("UAV", yaw_deg=10.0, pitch_deg=5.0, roll_deg=0.0, speed_m_s=0.0, path_angle_deg=0.0)  # nose 5 down
    h.advance(10.0)
    assert h.dev.gimbal.vehicle.pitch == -5.0
    assert h.dev.gimbal.pitch_deg == pytest.approx(-15.0)
    assert h.decode(only(h.ask("GIC", read=True)))["pitch_deg"] == pytest.approx(20.0)


def test_fai_needs_fae() -> None:
    h = DeviceHarness("C12")
    h.ask("FAI", yaw_deg=0.0, pitch_deg=10.0, roll_deg=0.0)
    assert h.dev.gimbal.vehicle.pitch == 0.0
    h.ask("FAE", state="on")
    h.ask("FAI", yaw_deg=0.0, pitch_deg=10.0, roll_deg=0.0)
    assert h.dev.gimbal.vehicle.pitch == 10.0


# -- attitude streams -------------------------------------------------------------------------------


@pytest.mark.parametrize("hz", [1, 25, 100])
def test_skydroid_gaa_streams_gac_at_the_requested_rate(hz: int) -> None:
    h = DeviceHarness("C12")
    h.ask("GAA", rate_hz=hz)
    out = h.advance(2.0)
    assert [f.ident for f in out] == ["GAC"] * (2 * hz)
    assert out[0].header == "#TP" and (out[0].src, out[0].dst) == ("G", "U")
    h.ask("GAA", rate_hz=0)
    assert h.advance(1.0) == []


def test_stream_samples_the_moving_gimbal() -> None:
    h = DeviceHarness("C10")  # documented GSY sign (the C12's is inverted: errata E29)
    h.ask("GAA", rate_hz=10)
    h.ask("GSY", yaw_rate_deg_s=12.0)
    yaws = [h.decode(f)["yaw_deg"] for f in h.advance(2.0)]
    assert yaws == sorted(yaws) and yaws[-1] > yaws[0] + 15


def test_topotek_gia_stream_and_query_per_host() -> None:
    h = DeviceHarness("SIP", topotek_stream_hz=20)
    h.ask("GIA", state="on")
    out = h.advance(1.0)
    assert len(out) == 20 and {f.ident for f in out} == {"GIA"}
    assert out[0].rw == "r" and out[0].dst == "P"
    assert h.decode(only(h.ask("GIA", read=True)))["state"] == "on"
    other = h.dev.receive("other-host", req("SIP", "GIA", read=True))
    assert b"GIA00" in other[0].data


# -- camera ------------------------------------------------------------------------------------------


def test_topotek_recording_and_photo_replies_carry_file_indexes() -> None:
    h = DeviceHarness("SIP")
    f = only(h.ask("REC", action="start"))
    assert f.data == b"1100000001" and f.header == "#tp"
    assert h.dev.camera.recording
    assert only(h.ask("REC", action="toggle")).data == b"0000000001"
    h.ask("REC", action="toggle")
    assert h.dev.camera.record_index == 2
    f = only(h.ask("CAP", mode="visible"))
    assert h.decode(f) == {"state": "taken", "file_index": 1}
    assert h.dev.camera.photos_taken == 1


def test_sd_card_falls_while_recording_and_per_photo() -> None:
    h = DeviceHarness("C12")
    before = h.decode(only(h.ask("SDC", read=True)))["remaining_mb"]
    h.ask("CAP")
    after_photo = h.decode(only(h.ask("SDC", read=True)))["remaining_mb"]
    assert after_photo < before
    h.ask("REC", action="start")
    h.advance(60.0)
    assert h.decode(only(h.ask("REC", read=True)))["state"] == "recording"
    assert h.decode(only(h.ask("SDC", read=True)))["remaining_mb"] < after_photo - 20


def test_no_card_is_answered_as_each_dialect_says() -> None:
    sky, top = DeviceHarness("C12"), DeviceHarness("SIP")
    sky.dev.camera.sd_present = top.dev.camera.sd_present = False
    assert only(sky.ask("SDC", read=True)).data == b"0000000000"
    assert only(top.ask("SDC", read=True, which="remaining")).data == b"NNNNN"
    assert only(top.ask("CAP", mode="visible")).ident == ERROR


def test_zoom_moves_while_zooming_and_zmp_follows_the_stop() -> None:
    h = DeviceHarness("SIP")
    h.ask("ZMC", action="zoom_in")
    h.advance(1.0)
    mid = h.decode(only(h.ask("ZOM", read=True)))["zoom_pos"]
    h.advance(0.5)
    out = h.ask("ZMC", action="stop")
    assert [f.ident for f in out] == ["ZMC", "ZMP"]
    zmp = h.decode(out[1])
    assert zmp["zoom_pos"] > mid > 0
    assert 1.0 < zmp["magnification_x"] < 10.0
    # running into the end stops the motor and reports by itself
    h.ask("ZMC", action="zoom_in")
    reports = h.advance(5.0)
    assert [f.ident for f in reports] == ["ZMP"] and h.decode(reports[0])["magnification_x"] == 10.0


def test_digital_zoom_per_dialect() -> None:
    sky, top = DeviceHarness("C12"), DeviceHarness("SIP")
    sky.ask("DZM", zoom="3x")
    sky.ask("DZM", zoom="zoom_in")
    assert sky.decode(only(sky.ask("DZM", read=True)))["zoom"] == "4x"
    assert sky.dev.camera.zoom_x == 4.0
    top.ask("DZM", lens="visible", zoom=2.5)
    top.ask("DZM", lens="thermal", zoom="step_in")
    assert top.decode(only(top.ask("DZM", read=True))) == {"thermal_zoom_x": 1.5, "visible_zoom_x": 2.5}


def test_thermal_palette_tables_and_stepping() -> None:
    sky, top = DeviceHarness("C12"), DeviceHarness("SIP")
    sky.ask("IMG", palette="ironbow")
    assert sky.decode(only(sky.ask("IMG", read=True)))["palette"] == "ironbow"
    top.ask("IMG", palette="next")
    assert top.decode(only(top.ask("IMG", read=True)))["palette"] == "lava"
    top.ask("IMG", palette="previous")
    top.ask("IMG", palette="previous")
    assert top.decode(only(top.ask("IMG", read=True)))["palette"] == "black_hot"


def test_c13_thermal_settings_stored_and_unsupported_elsewhere() -> None:
    h = DeviceHarness("C13")
    for ident, name, value in (("TSM", "scene", "high_contrast"), ("TIB", "brightness", 77), ("TGM", "gamma", 12)):
        h.ask(ident, **{name: value})
        assert h.decode(only(h.ask(ident, read=True)))[name] == value
    assert only(DeviceHarness("C12").ask("TSM", read=True)).ident == ERROR


def test_model_limit_answered_with_error() -> None:
    h = DeviceHarness("C12")
    assert only(h.ask("TAS", interval_s=50)).ident == ERROR  # C12: 0..25
    assert only(h.ask("TAS", interval_s=20)).ident == "TAS"


def test_temperature_reports_from_the_scene() -> None:
    h = DeviceHarness("SIP")
    h.ask("GIY", yaw_deg=30.0, speed_deg_s=9.9)
    h.ask("GIP", pitch_deg=20.0, speed_deg_s=9.9)  # down 20: the hot spot
    h.advance(10.0)
    f = only(h.ask("TMP", read=True, x_px=320, y_px=256))
    assert h.decode(f)["avg_temp_c"] > 60
    reports = [h.decode(x) for x in h.advance(2.0) if x.ident == "TMP"]
    assert len(reports) == 2 and reports[0]["hot_temp_c"] > 60 and reports[0]["center_temp_c"] > 60


# -- rangefinder and target solution -----------------------------------------------------------------


def test_lrf_distance_from_pitch_and_altitude_then_target_solution() -> None:
    h = DeviceHarness("SIP")
    h.ask("GIP", pitch_deg=30.0, speed_deg_s=9.9)  # 30 down
    h.advance(10.0)
    h.ask("ALT", alt_m=100.0)
    f = h.ask("LRF", action="single")
    assert [x.ident for x in f] == ["LRF", "LRF"]
    assert h.decode(f[1])["distance_m"] == pytest.approx(200.0)
    h.ask("LAT", lat_deg=22.5)
    h.ask("LON", lon_deg=113.9)
    h.ask("AZI", azimuth_deg=0.0)
    out = h.ask("LRF", action="single")
    assert [x.ident for x in out] == ["LRF", "LRF", "LAT", "LON"]
    lat = h.dialect.decode(out[2]).fields
    assert lat is not None
    # 200 m slant at 30 deg down = 173.2 m north
    assert lat["lat_deg"] == pytest.approx(22.5 + 173.2 / 111195, abs=2e-6)
    h.ask("ALT", alt_m=5000.0)  # 10 km: beyond 1500 m
    assert h.ask("LRF", action="single")[1].data == b"ERR"


def test_lrf_continuous_until_stop() -> None:
    h = DeviceHarness("SIP")
    h.ask("GIP", pitch_deg=45.0, speed_deg_s=9.9)
    h.ask("ALT", alt_m=50.0)
    h.ask("LRF", action="continuous")
    assert [f.ident for f in h.advance(3.0)].count("LRF") == 3
    h.ask("LRF", action="stop")
    assert h.advance(3.0) == []


def test_c13_slr() -> None:
    h = DeviceHarness("C13")
    h.dev.gimbal.pitch_axis.pos = -30.0
    h.ask("ALT", alt_m=20.0)
    assert h.decode(only(h.ask("SLR", read=True)))["distance_m"] == pytest.approx(40.0)


# -- network, version, quirks ----------------------------------------------------------------------


def test_network_settings_stored_answered_and_reset() -> None:
    h = DeviceHarness("SIP")
    h.ask("IPV", address="127.1.2.3")
    assert h.decode(only(h.ask("IPV", read=True)))["address"] == "127.1.2.3"
    assert h.dev.network.ip == "127.1.2.3" and h.dev.dirty
    h.ask("RST", action="reset")
    assert h.dev.network.ip == NetworkState().ip  # the factory default


def test_arducopter_identity_queries() -> None:
    h = DeviceHarness("SIP")
    assert h.decode(only(h.ask("PA2", read=True)))["model"] == "SIP"
    assert h.decode(only(h.ask("VSN", read=True)))["version"] == "1.2.3"
    trc = only(h.ask("TRC", read=True))
    assert trc.data[1:2] == b"0"
    h.ask("TRC", action="start")
    assert only(h.ask("TRC", read=True)).data[1:2] == b"1"


def test_c12_ver_wrong_length_quirk_by_default() -> None:
    h = DeviceHarness("C12")
    reply = h.dev.receive("p", req("C12", "VER", read=True))[0].data
    assert reply == b"#tpDU3rVER0105025A"  # byte-for-byte what a real C12 sends
    off = Device("C12", quirk_overrides={"ver_wrong_length": False})
    assert off.receive("p", req("C12", "VER", read=True))[0].data.startswith(b"#tpDU6rVER")


def test_lowercase_crlf_and_no_motion_echo_quirks() -> None:
    h = DeviceHarness("SIP", quirk_overrides={"lowercase_header": True, "crlf": True, "no_motion_echo": True})
    assert h.dev.receive("p", req("SIP", "GAY", yaw_deg=10.0, speed_deg_s=9.9)) == []
    out = h.dev.receive("p", req("SIP", "GAC", read=True))[0].data
    assert out.startswith(b"#tp") and out.endswith(b"\r\n")
    h.advance(5.0)
    assert h.dev.gimbal.yaw_deg == pytest.approx(10.0)  # obeyed without an echo


def test_unknown_quirk_is_rejected_by_name() -> None:
    with pytest.raises(ValueError, match=r"unknown quirk 'loud'.*lowercase_header"):
        Device("C12", quirk_overrides={"loud": True})
