"""Fixtures that run a test on both paths: the pure Python parser/decoder and the C fast path."""

from __future__ import annotations

import os
from collections.abc import Callable
from typing import Any

import pytest

from topgimbal import _speedups
from topgimbal.protocol import Diagnostic, Dialect, Frame, FrameParser, Message

FAST_WANTED = os.environ.get("TOPGIMBAL_PURE", "") in ("", "0")
SCAN_FLAGS = _speedups.scan_flags(FrameParser)


class FastFrameParser(FrameParser):
    """FrameParser with the C scan dropped in (what protocol/parser.py will do when adopting it)."""


_fast_scan = _speedups.make_scan(Frame, Diagnostic, SCAN_FLAGS)
if _fast_scan is not None:
    FastFrameParser._scan = _fast_scan  # type: ignore[method-assign]


def fast_decoder(dialect: Dialect) -> Callable[[Frame], Message]:
    dec = _speedups.make_decoder(dialect, Message, dialect.decode)
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
