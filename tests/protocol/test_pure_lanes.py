"""The pure path's two shortcuts give exactly what the general code gives.

- Form decoders unpack a run of whole-byte hex fields with one unhexlify + struct.unpack
  (`Form._build_decoder`); each field's own `codec.decode` is the reference.
- A datagram that is exactly one good frame is judged without the scan loop
  (`FrameParser._feed_py`); the same bytes fed as a stream and then flushed go through the loop.
"""

from __future__ import annotations

import random
from typing import cast

import pytest

from topgimbal.errors import FieldValueError
from topgimbal.protocol import Frame, get_dialect
from topgimbal.protocol.examples import example_fields, example_values
from topgimbal.protocol.fields import Codec, HexInt
from topgimbal.protocol.forms import Form
from topgimbal.protocol.parser import PureFrameParser

pytestmark = pytest.mark.virtual

DIALECTS = [get_dialect("skydroid"), get_dialect("topotek")]


def _forms_with_packed_fields() -> list[tuple[str, str, Form]]:
    out = []
    for d in DIALECTS:
        for spec in d.commands.values():
            for form in spec.forms:
                if any(isinstance(f.codec, HexInt) and f.codec.packed_plan() for f in form.fields):
                    out.append((d.name, spec.ident, form))
    return out


PACKED = _forms_with_packed_fields()


def test_some_forms_take_the_packed_decoder() -> None:
    assert len(PACKED) > 20  # GAC, GAY, PTZ rates ... in both dialects


@pytest.mark.parametrize(("dialect", "ident", "form"), PACKED, ids=[f"{d}-{i}-{f.title}" for d, i, f in PACKED])
def test_packed_decoder_matches_each_codec(dialect: str, ident: str, form: Form) -> None:
    rnd = random.Random(f"{dialect}{ident}{form.title}")
    datas = [form.encode(example_fields(form))]
    for _ in range(50):  # random digits, both cases: every raw value, not only encodable ones
        datas.append(b"".join(_random_raw(f.codec, rnd) for f in form.fields))
    for data in datas:
        if not form.accepts_length(len(data)):
            continue
        got = form.decoder(data)
        pos = 0
        for f in form.fields:
            width = f.codec.width if f.codec.width is not None else len(data) - pos
            want = f.codec.decode(data[pos : pos + width])
            assert got[f.name] == want and type(got[f.name]) is type(want), (f.name, data)
            pos += width


def _random_raw(codec: Codec, rnd: random.Random) -> bytes:
    if isinstance(codec, HexInt):
        return bytes(rnd.choice(b"0123456789ABCDEFabcdef") for _ in range(codec.width))
    return codec.encode(rnd.choice(example_values(codec)))


@pytest.mark.parametrize("bad", [b"G", b"-", b" ", b"\x00", b"x"])
def test_packed_decoder_rejects_a_non_hex_digit_naming_the_field(bad: bytes) -> None:
    form = get_dialect("skydroid").command("GAC").forms[1]
    assert [f.name for f in form.fields] == ["yaw_deg", "pitch_deg", "roll_deg"]
    data = bytearray(b"000100020003")
    data[5] = bad[0]  # in pitch_deg
    with pytest.raises(FieldValueError) as err:
        form.decode(bytes(data))
    assert err.value.field == "pitch_deg"
    assert get_dialect("skydroid").decode(_gac(bytes(data))).fields is None


def _gac(data: bytes) -> Frame:
    return Frame("#TP", "G", "U", "r", "GAC", data)


def _datagrams() -> list[bytes]:
    """Every example frame of both dialects, plus variants the shortcut must hand to the loop."""
    out = []
    for d in DIALECTS:
        for spec in d.commands.values():
            for form in spec.forms:
                data = form.encode(example_fields(form))
                device = spec.address or "G"
                src, dst = ("U", device) if form.direction == "request" else (device, "U")
                out.append(Frame(d.header_for(spec, len(data), dst), src, dst, form.rw, spec.ident, data).to_bytes())
    good = get_dialect("skydroid").encode("PTZ", action="up").to_bytes()
    out += [
        good[:-2] + good[-2:].lower(),  # a lower-case checksum is good
        good[:-1] + (b"0" if good[-1:] != b"0" else b"1"),  # a bad checksum
        good + b"\r\n",  # a line end after the frame
        good[:-3],  # too short for its length
        good + good,  # two frames
        good[:12] + b"#" + good[13:],  # a '#' inside
        b"garbage" + good,
    ]
    return out


@pytest.mark.parametrize("max_data_length", [1024, 2])
def test_one_frame_datagram_matches_the_scan_loop(max_data_length: int) -> None:
    datagrams = _datagrams()
    assert len(datagrams) > 300
    for dg in datagrams:
        lane = PureFrameParser(max_data_length=max_data_length)
        loop = PureFrameParser(max_data_length=max_data_length)
        got = lane.feed_datagram(dg)
        want = loop.feed(dg) + loop.flush()  # the loop: a stream that then ends
        assert got == want, dg
        assert [type(e) for e in got] == [type(e) for e in want]
        assert lane.stats == loop.stats, dg
        assert lane.buffered == 0
        for view in (bytearray(dg), memoryview(dg)):  # other buffer types take the loop, same answer
            assert PureFrameParser(max_data_length=max_data_length).feed_datagram(cast(bytes, view)) == want


def test_one_frame_datagram_decodes_like_decode() -> None:
    for d in DIALECTS:
        for dg in _datagrams():
            got = PureFrameParser().feed_messages(dg, d._decode_py, final=True)
            frames = PureFrameParser().feed_datagram(dg)
            assert got == [d._decode_py(e) if type(e) is Frame else e for e in frames]


def test_a_held_partial_frame_is_not_skipped_by_the_shortcut() -> None:
    sky = get_dialect("skydroid")
    good = sky.encode("PTZ", action="up").to_bytes()
    p, q = PureFrameParser(), PureFrameParser()
    assert p.feed(good[:5]) == [] and q.feed(good[:5]) == []
    got = p.feed_messages(good, sky._decode_py, final=True)
    want = [sky._decode_py(e) if type(e) is Frame else e for e in q.feed(good) + q.flush()]
    assert got == want
    # the held bytes are reported before the frame, which is still found
    assert not isinstance(got[0], type(got[-1])) and got[-1].fields == {"action": "up"}
