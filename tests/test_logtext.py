"""A peer's text in a log line: UTF-8-encodable, one line, bounded."""

from __future__ import annotations

import io
import logging

import pytest

from topgimbal.logtext import MAX_LOGGED_CHARS, untrusted

pytestmark = pytest.mark.virtual


def test_lone_surrogates_become_backslash_escapes() -> None:
    hostile = "evil\udcff\udcfe.example"
    safe = untrusted(hostile)
    assert safe == "evil\\udcff\\udcfe.example"
    safe.encode("utf-8")


def test_controls_cannot_forge_a_log_line() -> None:
    assert untrusted("a\r\nWARNING forged\x1b[31m") == "a\\r\\nWARNING forged\\x1b[31m"


def test_ordinary_text_is_unchanged() -> None:
    for text in ("camera-bench.example:8080", "云台 C12", "/api/status?x=1"):
        assert untrusted(text) == text


def test_long_text_is_cut_and_says_how_much() -> None:
    safe = untrusted("x" * (MAX_LOGGED_CHARS + 50))
    assert safe.startswith("x" * MAX_LOGGED_CHARS) and safe.endswith("(+50 chars)")
    assert untrusted(b"\xff") == "b'\\xff'"  # not a str: its str()


def test_a_utf8_log_file_keeps_the_record() -> None:
    # the bug: a record with a lone surrogate is dropped by a UTF-8 stream handler (an error on stderr)
    out = io.BytesIO()
    stream = io.TextIOWrapper(out, encoding="utf-8")
    handler = logging.StreamHandler(stream)
    logger = logging.getLogger("topgimbal.test_logtext")
    logger.addHandler(handler)
    logger.propagate = False
    try:
        logger.warning("refused Host %s", untrusted("rebind\udcff.example"))
        handler.flush()
    finally:
        logger.removeHandler(handler)
    assert out.getvalue() == b"refused Host rebind\\udcff.example\n"
