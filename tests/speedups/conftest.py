"""Fixtures that run a test on both paths: the pure Python parser/decoder and the C fast path."""

from __future__ import annotations

import os
from collections.abc import Callable
from typing import Any

import pytest

from topgimbal import _speedups
from topgimbal.protocol import Diagnostic, Dialect, Frame, FrameParser, Message

FAST_WANTED = os.environ.get("TOPGIMBAL_PURE", "") in ("", "0")


class PureFrameParser(FrameParser):
    """The pure Python parser, also once protocol/parser.py has adopted the fast scan (it then
    keeps the pure one as `_scan_py`)."""


PureFrameParser._scan = getattr(FrameParser, "_scan_py", FrameParser._scan)  # type: ignore[method-assign]
SCAN_FLAGS = _speedups.scan_flags(PureFrameParser)


class FastFrameParser(FrameParser):
    """FrameParser with the C scan dropped in (what protocol/parser.py will do when adopting it)."""


_fast_scan = _speedups.make_scan(Frame, Diagnostic, SCAN_FLAGS)
if _fast_scan is not None:
    FastFrameParser._scan = _fast_scan  # type: ignore[method-assign]


def pure_decode(dialect: Dialect) -> Callable[[Frame], Message]:
    """Dialect.decode on the pure path (`_decode_py` once catalog.py has adopted the fast one)."""
    return getattr(dialect, "_decode_py", dialect.decode)  # type: ignore[no-any-return]


def fast_decoder(dialect: Dialect) -> Callable[[Frame], Message]:
    dec = _speedups.make_decoder(dialect, Message, pure_decode(dialect))
    assert dec is not None, _speedups.status()
    return dec  # type: ignore[no-any-return]


@pytest.fixture(params=["pure", "fast"])
def parser_cls(request: Any) -> type[FrameParser]:
    """FrameParser on each path (the fast one only where the extension is in use)."""
    if request.param == "fast":
        if not _speedups.enabled():
            pytest.skip(f"C fast path not in use: {_speedups.status()}")
        return FastFrameParser
    return FrameParser
