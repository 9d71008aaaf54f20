"""Properties over the whole catalog (hypothesis, bounded): every frame the encoder emits is decoded
by its own dialect to the same values; hostile values only ever raise FieldValueError and never
inject a second frame; hostile bytes and unknown (identifier, control) pairs never make decoding
raise."""

from __future__ import annotations

import os
from typing import Any

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from topgimbal.errors import FieldValueError
from topgimbal.protocol import REQUEST, CommandSpec, Dialect, Form, Frame, FrameParser, decode_any, get_dialect
from topgimbal.protocol.dialects import DIALECT_NAMES
from topgimbal.protocol.fields import BinInt, RawData
from topgimbal.protocol.frame import make_frame

from .strategies import HOSTILE, close, values

pytestmark = [pytest.mark.virtual, pytest.mark.fuzz]

DIALECTS = [get_dialect(n) for n in DIALECT_NAMES]
FORMS = [
    pytest.param(d, spec, form, id=f"{d.name}-{spec.ident}-{form.rw}-{form.direction}-{i}")
    for d in DIALECTS
    for spec in d.commands.values()
    for i, form in enumerate(spec.forms)
]
FIELDS = [
    pytest.param(d, spec, form, f, id=f"{d.name}-{spec.ident}-{i}-{f.name}")
    for d in DIALECTS
    for spec in d.commands.values()
    for i, form in enumerate(spec.forms)
    for f in form.fields
]
# Bounded so the suite stays fast; TOPGIMBAL_DEEP=400 for a deep local run.
FAST = settings(
    max_examples=int(os.environ.get("TOPGIMBAL_DEEP", "25")),
    deadline=None,
    suppress_health_check=[HealthCheck.too_slow],
)


def frame_for(dialect: Dialect, spec: CommandSpec, form: Form, data: bytes) -> Frame:
    if form.direction == REQUEST:
        src, dst = dialect.host_addresses[0], spec.address
    else:
        src, dst = spec.address, dialect.host_addresses[0]
    header = dialect.header_for(spec, len(data), dst)
    return make_frame(spec.ident, data, src=src, dst=dst, rw=form.rw, header=header)


def form_values(form: Form) -> st.SearchStrategy[dict[str, Any]]:
    return st.fixed_dictionaries({f.name: values(f.codec) for f in form.fields})


@pytest.mark.parametrize(("dialect", "spec", "form"), FORMS)
@FAST
@given(data=st.data())
def test_every_emitted_frame_decodes_to_the_values_sent(
    dialect: Dialect, spec: CommandSpec, form: Form, data: st.DataObject
) -> None:
    sent = data.draw(form_values(form)) if form.const is None else {}
    payload = form.encode(sent, spec.ident)
    frame = frame_for(dialect, spec, form, payload)
    assert FrameParser().feed(frame.to_bytes()) == [frame]
    msg = dialect.decode(frame)
    assert msg.error is None and msg.fields is not None, (frame, msg.error)
    assert msg.form is form, (frame, form.title, msg.form.title if msg.form else None)
    codecs = {f.name: f.codec for f in form.fields}
    for name, value in sent.items():
        assert close(codecs[name], value, msg.fields[name]), (frame, name, value, msg.fields[name])
    # Decoding loses nothing the wire can carry: the decoded values encode to the same bytes.
    assert form.encode(msg.fields, spec.ident) == payload


@pytest.mark.parametrize(("dialect", "spec", "form", "field"), FIELDS)
@settings(max_examples=15, deadline=None)
@given(value=HOSTILE)
def test_hostile_values_raise_field_value_error_or_stay_one_frame(
    dialect: Dialect, spec: CommandSpec, form: Form, field: Any, value: Any
) -> None:
    try:
        raw = field.codec.encode(value, field.name)
    except FieldValueError as exc:
        assert exc.field == field.name and exc.allowed
        return
    assert isinstance(raw, bytes) and field.codec.min_width <= len(raw) <= field.codec.max_width
    if not isinstance(field.codec, BinInt) and not (isinstance(field.codec, RawData) and field.codec.binary):
        assert not {ord("#"), 13, 10} & set(raw), (field.name, value, raw)
        assert raw.isascii() or isinstance(field.codec, RawData)


@pytest.mark.parametrize(("dialect", "spec", "form"), FORMS)
@settings(max_examples=10, deadline=None)
@given(data=st.binary(max_size=24))
def test_any_data_decodes_or_says_why(dialect: Dialect, spec: CommandSpec, form: Form, data: bytes) -> None:
    try:
        form.decode(data)
    except ValueError:
        pass
    frame = Frame("#tp" if len(data) <= 15 else "#tP", "U", spec.address, form.rw, spec.ident, data)
    msg = dialect.decode(frame)
    assert (msg.fields is None) == (msg.error is not None)


@settings(max_examples=300, deadline=None)
@given(
    ident=st.text(alphabet="ABCGMPSTYZ019#é", min_size=3, max_size=3),
    rw=st.sampled_from(["r", "w", "", "x", "R", "\x00", "#"]),
    src=st.sampled_from("UMDEPG"),
    dst=st.sampled_from("UMDEPG"),
    data=st.binary(max_size=20),
)
def test_every_identifier_and_control_pair_decodes_or_is_an_unknown_form(
    ident: str, rw: str, src: str, dst: str, data: bytes
) -> None:
    frame = Frame("#tp", src, dst, rw, ident, data)
    for d in DIALECTS:
        msg = d.decode(frame)
        assert msg.dialect == d.name
        if msg.fields is None:
            assert msg.error
            if msg.spec is not None and rw not in ("r", "w", ""):
                assert "unknown form" in msg.error
    msg = decode_any(frame)
    assert msg.fields is not None or msg.error
