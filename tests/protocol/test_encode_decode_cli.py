"""What `encode` prints for a binary-payload command decodes again (issue 26, item 6: TOPOTEK GPS,
UAV and LOC came out as \\x-escaped text that `decode` read as the escape characters themselves, so
the checksum and length never fit: 113 failures in a sweep of values)."""

from __future__ import annotations

import json

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from topgimbal.cli.main import main
from topgimbal.protocol import get_dialect
from topgimbal.protocol.frame import bytes_from_text, parse_frame

pytestmark = pytest.mark.virtual

TOP = get_dialect("topotek")
BINARY = ["GPS", "UAV", "LOC"]


def run(argv: list[str], capsys: pytest.CaptureFixture[str]) -> tuple[int, str]:
    rc = main(argv)
    return rc, capsys.readouterr().out


def field_values(ident: str) -> st.SearchStrategy[dict[str, float]]:
    """Any value each field of the command's write form takes, on its step (BinInt range and scale)."""
    form = TOP.command(ident).request_form("w")
    parts = {}
    for f in form.fields:
        d = f.codec.describe()
        if d.get("min") is None:
            continue  # LOC's reserved bytes: their default
        scale = f.codec.scale
        lo, hi = round(d["min"] / scale), round(d["max"] / scale)
        parts[f.name] = st.integers(lo, hi).map(lambda n, s=scale: round(n * s, 6))
    return st.fixed_dictionaries(parts)


@pytest.mark.parametrize("ident", BINARY)
@settings(max_examples=40, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(data=st.data())
def test_encode_output_decodes_again(ident: str, data: st.DataObject, capsys: pytest.CaptureFixture[str]) -> None:
    values = data.draw(field_values(ident))
    pairs = [f"{k}={v}" for k, v in values.items()]
    rc, out = run(["encode", ident, *pairs, "--dialect", "topotek"], capsys)
    assert rc == 0
    printed = out.strip()
    assert "\n" not in printed and printed.isprintable()  # one line a terminal shows as it is
    rc, out = run(["decode", printed, "--dialect", "topotek", "--json"], capsys)
    rec = json.loads(out)
    assert rc == 0 and rec["ok"] and rec["fields_error"] is None, rec
    expected = TOP.decode(TOP.encode(ident, **values)).fields
    assert rec["fields"] == pytest.approx(expected)
    # and the other way: a decoded frame's bytes, printed as encode prints them, are the same bytes
    frame = parse_frame(bytes_from_text(printed))
    assert frame.text() == printed and frame == TOP.encode(ident, **values)


@given(st.binary(max_size=40))
def test_text_and_bytes_map_one_to_one(raw: bytes) -> None:
    from topgimbal.protocol.frame import _ESCAPES

    text = raw.decode("latin-1").translate(_ESCAPES)
    assert bytes_from_text(text) == raw


def test_a_backslash_and_plain_text_decode_as_typed(capsys: pytest.CaptureFixture[str]) -> None:
    assert bytes_from_text("#TPUD2wREC003E") == b"#TPUD2wREC003E"
    assert bytes_from_text(r"a\\x41\x41\q") == b"a\\x41A\\q"
    rc, out = run(["decode", "#TPUD2wREC€", "--json"], capsys)
    assert rc == 1 and "\\xNN" in json.loads(out)["error"]
