"""Untrusted input never raises out of the device: random frames of every model (valid identifiers
with random data, random identifiers, every identifier with every control and address), random
byte streams; and a handler that fails becomes the error frame and one log line."""

from __future__ import annotations

import logging
import string

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from topgimbal.protocol import Frame, FrameParser, all_models, get_model, make_frame
from topgimbal.sim import FakeClock
from topgimbal.sim.context import Request, SimState
from topgimbal.sim.device import Device, Outgoing

pytestmark = pytest.mark.virtual

MODELS = sorted(all_models())
ADDRESSES = "UMDEPGX"
HEADERS = ("#TP", "#tp", "#tP", "#Tp")
IDENT_CHARS = string.ascii_uppercase + string.digits
FUZZ = settings(max_examples=300, deadline=None, suppress_health_check=[HealthCheck.too_slow])


def devices() -> dict[str, Device]:
    return {m: Device(m, clock=FakeClock()) for m in MODELS}


def replies_are_frames(out: list[Outgoing]) -> None:
    """Each reply parses as frames (the C12's VER with its wrong length character, as a real one
    sends it, also carries the parser's note about the length)."""
    for o in out:
        parsed = FrameParser().feed_datagram(o.data)
        assert any(isinstance(p, Frame) for p in parsed), o.data
        assert all(isinstance(p, Frame) or p.kind == "length_mismatch" for p in parsed), o.data


@st.composite
def frames(draw: st.DrawFn, idents: st.SearchStrategy[str]) -> bytes:
    ident = draw(idents)
    header = draw(st.sampled_from(HEADERS))
    data = draw(st.binary(max_size=40) | st.text(alphabet=string.hexdigits + "N.-+:!", max_size=20).map(str.encode))
    if header in ("#TP", "#tp"):
        data = data[:15]
    rw = "w" if header == "#Tp" else draw(st.sampled_from("rw"))
    src, dst = draw(st.sampled_from(ADDRESSES)), draw(st.sampled_from(ADDRESSES))
    try:
        return make_frame(ident, data, src=src, dst=dst, rw=rw, header=header).to_bytes()
    except ValueError:
        return b"#" + header[1:].encode() + src.encode() + dst.encode() + b"2" + rw.encode() + ident.encode() + data


KNOWN = sorted({i for m in MODELS for i in get_model(m)[0].commands})


@FUZZ
@given(model=st.sampled_from(MODELS), frame=frames(st.sampled_from(KNOWN)))
def test_known_identifiers_with_random_data_never_raise(model: str, frame: bytes) -> None:
    dev = Device(model, clock=FakeClock())
    replies_are_frames(dev.receive("host", frame))


@FUZZ
@given(model=st.sampled_from(MODELS), frame=frames(st.text(alphabet=IDENT_CHARS, min_size=3, max_size=3)))
def test_random_identifiers_never_raise(model: str, frame: bytes) -> None:
    dev = Device(model, clock=FakeClock())
    replies_are_frames(dev.receive("host", frame))


@FUZZ
@given(model=st.sampled_from(MODELS), chunks=st.lists(st.binary(max_size=64), max_size=8))
def test_random_byte_streams_never_raise(model: str, chunks: list[bytes]) -> None:
    dev = Device(model, clock=FakeClock())
    for chunk in chunks:
        replies_are_frames(dev.receive("tcp", chunk, datagram=False))
        replies_are_frames(dev.receive("udp", chunk))
    replies_are_frames(dev.tick())


@pytest.mark.parametrize("model", MODELS)
def test_every_identifier_control_and_address_is_answered_or_dropped(model: str) -> None:
    """Each (identifier, control) pair of both dialects, from each host address to each device
    address, with data of each length a form takes and one it does not: a reply or nothing."""
    dev = Device(model, clock=FakeClock())
    d = dev.dialect
    sent = 0
    for ident in KNOWN:
        spec = d.commands.get(ident)
        lengths = {0, 2, 17} | ({f.min_length for f in spec.forms} if spec else set())
        for rw in "rw":
            for src in "UP":
                for dst in "MDEG":
                    for n in sorted(lengths):
                        data = (b"00" * 9)[:n] if n <= 15 else b"0" * n
                        frame = make_frame(ident, data, src=src, dst=dst, rw=rw, header="#TP" if n <= 15 else "#tP")
                        replies_are_frames(dev.receive("host", frame.to_bytes()))
                        sent += 1
    assert sent > 500 and dev.errors == 0


def test_a_failing_handler_is_an_error_frame_and_one_log_line(caplog: pytest.LogCaptureFixture) -> None:
    def broken(state: SimState, msg: object, req: Request) -> None:
        raise KeyError("zoom")

    dev = Device("C12", clock=FakeClock(), handlers={"DZM": broken})
    request = get_model("C12")[0].encode("DZM", zoom="2x")
    with caplog.at_level(logging.WARNING, logger="topgimbal.sim"):
        out = dev.receive("host", request.to_bytes())
        again = dev.receive("host", get_model("C12")[0].encode("GAC", read=True).to_bytes())
    [reply] = [f for o in out for f in FrameParser().feed_datagram(o.data)]
    assert isinstance(reply, Frame) and reply.ident == "ERE" and (reply.src, reply.dst) == (request.dst, request.src)
    assert dev.errors == 1
    [record] = caplog.records
    assert "DZM" in record.getMessage() and "KeyError" in record.getMessage()
    assert again and b"GAC" in again[0].data  # the device goes on


def test_new_dzm_forms_and_slr_limit_no_longer_fail() -> None:
    """The forms that used to raise out of the DZM handler or get the error frame."""
    for model in ("C12", "C11", "SIP"):
        d, m = get_model(model)
        dev = Device(m, clock=FakeClock())
        dev.camera.video_output = True
        for title, values in (
            ("image and zoom (4 characters)", {"image": "thermal", "zoom": 2.5}),
            ("image and magnification (6 characters)", {"image": "visible", "magnification_x": 3.0}),
        ):
            request = d.encode("DZM", form=title, **values)
            [o] = dev.receive("host", request.to_bytes())
            assert o.data == request.swapped().to_bytes()
        assert dev.camera.thermal_digital_zoom_x == 2.5 and dev.camera.digital_zoom_x == 3.0
    d, m = get_model("C13")
    dev = Device("C13", clock=FakeClock())
    request = d.encode("SLR", limit_m=20.0)
    [o] = dev.receive("host", request.to_bytes())
    assert o.data == request.swapped().to_bytes() and dev.settings["SLR"]["limit_m"] == 20.0


def test_a_failing_stream_report_ends_that_stream_and_logs_once(caplog: pytest.LogCaptureFixture) -> None:
    clock = FakeClock()
    dev = Device("SIP", clock=clock)
    d = dev.dialect
    dev.receive("a", d.encode("GIA", src="P", state="on").to_bytes())
    dev.receive("b", d.encode("GAA", src="P", state="on").to_bytes())
    [gia] = [s for s in dev.streams.values() if s.ident == "GIA"]

    def broken(state: SimState, s: object) -> list[Frame]:
        raise ValueError("no frame")

    gia.report = broken
    with caplog.at_level(logging.WARNING, logger="topgimbal.sim"):
        clock.advance(1.0)
        out = dev.tick()
    assert {o.peer for o in out} == {"b"} and len(out) == 10  # the other stream goes on
    assert list(dev.streams) == [("b", "GAC")] and dev.errors == 1
    [record] = caplog.records
    assert "GIA" in record.getMessage()
