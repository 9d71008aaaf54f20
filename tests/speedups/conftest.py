"""Both paths side by side: the pure Python parser/decoders and the C fast path.

The fast objects here are built from the extension whatever TOPGIMBAL_PURE says, so the
differential tests compare the two paths in both test runs (`make test` runs the suite with the
fast path, then again with TOPGIMBAL_PURE=1). The test machine has a compiler: a missing or stale
extension fails them."""

from __future__ import annotations

import functools
import os
from collections.abc import Callable
from typing import Any

import pytest

from topgimbal import _speedups
from topgimbal.protocol import DIALECT_NAMES, Dialect, Frame, FrameParser, Message, get_dialect
from topgimbal.protocol.dialects import _decode_any_py
from topgimbal.protocol.parser import PureFrameParser

FAST_WANTED = os.environ.get("TOPGIMBAL_PURE", "") in ("", "0")

__all__ = [
    "FAST_WANTED",
    "PureFrameParser",
    "ext",
    "fast_any_decoder",
    "fast_decoder",
    "fast_parser_cls",
    "pure_any_decoder",
    "pure_decode",
]


@functools.cache
def ext() -> Any:
    try:
        return _speedups.load_extension()
    except ImportError as exc:
        raise AssertionError(f"the C extension is not built here ({exc}): `pip install -e .` builds it") from None


@functools.cache
def fast_parser_cls() -> type[FrameParser]:
    """FrameParser with the C feed methods, built from the extension."""
    pure = {name: getattr(PureFrameParser, name) for name in _speedups.PARSER_METHODS}
    methods = _speedups.parser_methods(Frame, pure, ext=ext())
    assert methods is not None
    return type("FastFrameParser", (PureFrameParser,), dict(methods))


def pure_decode(dialect: Dialect) -> Callable[[Frame], Message]:
    """Dialect.decode on the pure path."""
    return dialect._decode_py


def fast_decoder(dialect: Dialect) -> Any:
    """Dialect.decode on the C path (falling back to the pure decoder exactly where it does)."""
    return _speedups.make_decoder(dialect, Message, pure_decode(dialect), ext=ext())


def pure_any_decoder(prefer: Dialect | None) -> Callable[[Frame], Message]:
    defaults = [get_dialect(n) for n in DIALECT_NAMES]

    def pure(frame: Frame) -> Message:
        return _decode_any_py(frame, prefer, defaults, Dialect._decode_py)

    return pure


def fast_any_decoder(prefer: Dialect | None) -> Any:
    """decode_any(frame, prefer) on the C path, with the pure decode_any as its fallback."""
    defaults = [fast_decoder(get_dialect(n)) for n in DIALECT_NAMES]
    first = fast_decoder(prefer) if prefer is not None else None
    return _speedups.make_any_decoder(first, defaults, pure_any_decoder(prefer), ext=ext())


@pytest.fixture(params=["pure", "fast"])
def parser_cls(request: Any) -> type[FrameParser]:
    """FrameParser on each path."""
    return fast_parser_cls() if request.param == "fast" else PureFrameParser
