"""Real-world frames decode with meaning, and frames no form takes cost little and keep their words
(issue 26, items 1 and 2)."""

from __future__ import annotations

import pytest

from topgimbal.protocol import decode_any, get_dialect, parse_frame
from topgimbal.protocol.dialects import _decode_any_py
from topgimbal.protocol.message import LazyText, Message

from .real_world import DEVICES, GROUND_STATION, frames, has_meaning, meaning_share, with_crc, without_meaning

pytestmark = pytest.mark.virtual

SKY, TOP = get_dialect("skydroid"), get_dialect("topotek")


def test_valid_real_world_frames_decode_with_meaning() -> None:
    every = frames()
    assert len(every) >= 90 and {s for s, _f in every} >= {GROUND_STATION, DEVICES}
    assert meaning_share() >= 0.97, [f.text() for _s, f in without_meaning()]


@pytest.mark.parametrize(
    ("text", "fields"),
    [
        ("#tpPD6wDZM00F08C84", {"image_code": 0, "ratio_mark": "F", "ratio_x": 14.0}),  # the source's own example
        ("#tpPD6wDZM03F12C", {"image_code": 3, "ratio_mark": "F", "ratio_x": 30.0}),  # an image code beyond 01
        ("#tpUD6wDZM01F019", {"image_code": 1, "ratio_mark": "F", "ratio_x": 2.5}),
    ],
)
@pytest.mark.parametrize("dialect", [SKY, TOP], ids=["skydroid", "topotek"])
def test_dzm_image_code_and_hex_ratio(text: str, fields: dict, dialect) -> None:
    raw = text.encode() if len(text) > 16 else with_crc(text)
    frame = parse_frame(raw)
    msg = dialect.decode(frame)
    assert msg.error is None and msg.fields == fields
    assert msg.form is not None and msg.form.title == "image code and ratio (F + 3 hex digits)"
    again = dialect.encode("DZM", image_code=fields["image_code"], ratio_x=fields["ratio_x"], src=frame.src)
    assert again.data == frame.data


def test_dzm_decimal_form_is_unchanged() -> None:
    msg = SKY.decode(parse_frame(with_crc("#tpUD6wDZM000140")))
    assert msg.fields == {"image": "visible", "magnification_x": 14.0}


def test_slr_fire_and_range_limit() -> None:
    fire = SKY.decode(parse_frame("#TPUD2wSLR015B"))
    assert fire.fields == {"action": "measure"} and SKY.encode("SLR", action="measure").text() == "#TPUD2wSLR015B"
    limit = SKY.decode(SKY.encode("SLR", limit_m=50.0))
    assert limit.fields == {"limit_m": 50.0}
    assert SKY.decode(parse_frame(with_crc("#TPUD2wSLR02"))).error is not None  # no other value is known


def test_trc_ready() -> None:
    assert TOP.decode(parse_frame(with_crc("#TPUD2wTRC02"))).fields == {"action": "ready"}


# -- item 2: failure paths are cheap, their words unchanged ------------------------------------------


UNUSUAL = [
    "#TPUD2wXYZ01",  # identifier in no catalog
    "#TPUG2wPTZ7F",  # a code no table has
    "#tpUG3wGAY123",  # a length no form takes
    "#tpUD6wDZM0AG08C",  # six characters no DZM form takes (G is neither a digit nor the F mark)
    "#TPUD2wSLR02",
]


@pytest.mark.parametrize("text", UNUSUAL)
def test_errors_are_worded_when_read_and_read_the_same(text: str) -> None:
    frame = parse_frame(with_crc(text))
    msg = decode_any(frame)
    assert msg.fields is None
    stored = tuple.__getitem__(msg, 4)
    assert isinstance(stored, (LazyText, str))
    if isinstance(stored, LazyText):
        assert stored._text is None  # nothing worded yet: the decode did not pay for it
    words = msg.error
    assert isinstance(words, str) and words and msg.error == words  # read twice: the same
    # the same words as the pure, explained path (the reference), and as the other decoders
    pure = _decode_any_py(frame, None, [SKY, TOP], decode=lambda d, f: d._decode_explained(f))
    assert pure.error == words
    assert msg.to_dict()["error"] == words
    assert msg == msg._replace(error=words)  # equal to the eager message


def test_content_error_names_the_field_as_before() -> None:
    msg = TOP.decode(parse_frame(with_crc("#TPUG2wPTZ7F")))
    assert msg.error is not None and msg.error.startswith("PTZ: action=b'7F' is not allowed: expected one of stop (00)")
    assert msg.error.endswith(
        "(b'7F' is not in the table ("
        + ", ".join(v.raw for v in TOP.command("PTZ").request_form("w").fields[0].codec.values)
        + "))"
    )
    msg = SKY.decode(parse_frame(with_crc("#tpUG3wGAY123")))
    assert msg.error == "3 data bytes; GAY (w) takes 6 or 6"


def test_a_message_reads_short() -> None:
    msg = SKY.decode(parse_frame("#TPUD2wSLR015B"))
    text = repr(msg)
    assert text == "<Message SLR laser_range fields={'action': 'measure'} frame='#TPUD2wSLR015B'>"
    assert str(msg) == text and len(text) < 200
    bad = decode_any(parse_frame(with_crc("#TPUD2wXYZ01")))
    assert repr(bad).startswith("<Message XYZ error=\"'XYZ' is not in the ") and len(repr(bad)) < 300
    assert isinstance(bad, Message) and has_meaning(parse_frame("#TPUD2wSLR015B"))
