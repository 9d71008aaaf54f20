"""JSON Lines stay one record per line for every reader (issue 35.7): U+0085, U+2028 and U+2029
are escaped by `decode --json` and the other JSONL writers; other text stays as it is."""

from __future__ import annotations

import json

import pytest

from topgimbal import jsonl
from topgimbal.cli.main import main

pytestmark = pytest.mark.virtual

BREAKERS = "\u0085\u2028\u2029"


@pytest.mark.parametrize("text", ["#TPUD2r\u2028EC00", "#TP\u0085D2rREC003E", "#TPUD2rREC003E\u2029x"])
def test_decode_json_is_one_line_per_record_for_splitlines(capsys, text: str) -> None:
    main(["decode", "--json", text])
    out = capsys.readouterr().out
    assert not any(ch in out for ch in BREAKERS), repr(out)
    lines = out.splitlines()  # what broke the record in two
    assert len(lines) == 1
    rec = json.loads(lines[0])
    assert any(ch in json.dumps(rec) for ch in ("\\u2028", "\\u0085", "\\u2029"))  # kept, escaped


def test_the_writer_escapes_only_the_line_breakers() -> None:
    obj = {"a": "x\u2028y\u0085z\u2029", "zh": "变焦", "nl": "a\nb"}
    text = jsonl.line(obj)
    assert len(text.splitlines()) == 1 and "变焦" in text
    assert json.loads(text) == obj
