"""The optional C fast path (libtopgimbal's scanner and codecs, compiled at install time).

A leaf below `protocol/`: it imports nothing from topgimbal; the protocol layer hands it its own
classes (`Frame`, `Message`) and dialects. Everything here gives None when the extension is not
built (no compiler at install), stale, or disabled with `TOPGIMBAL_PURE=1`; callers then keep the
pure Python path. Both paths give identical results (tests/speedups/).

    parser_methods(Frame, pure)            -> C versions of FrameParser's feed methods, or None
    make_decoder(dialect, Message, pure)   -> a drop-in for Dialect.decode, or None
    make_any_decoder(prefer, dialects, pure) -> a drop-in for decode_any(frame, prefer), or None
    recv_many()                            -> recvmmsg for an IPv4 UDP socket (Linux), or None
"""

from __future__ import annotations

import os
from collections.abc import Callable, Mapping, Sequence
from types import ModuleType
from typing import Any

# The decoders below are the C extension's objects: Dialect.decode / decode_any stand-ins whose
# types this package cannot name (it sits below protocol/ and imports nothing from it). `.spec`
# (which turns a catalog into the C tables) is imported when a decoder is first made: a
# one-frame `topgimbal decode` makes none.

ABI_VERSION = 3  # must match _ctop.c
PARSER_METHODS = ("feed", "feed_datagram", "flush", "feed_messages")  # _ctop.c: M_FEED ... M_MESSAGES


def load_extension() -> ModuleType:
    """The compiled extension whatever TOPGIMBAL_PURE says (the differential tests compare it with
    the pure path in both test runs); ImportError when it is not built or stale."""
    from . import _ctop  # type: ignore[attr-defined]

    if getattr(_ctop, "ABI_VERSION", None) != ABI_VERSION:
        raise ImportError("stale build of topgimbal._speedups._ctop (rebuild: pip install -e .)")
    return _ctop


_ext: ModuleType | None = None
_status = ""
if os.environ.get("TOPGIMBAL_PURE", "") not in ("", "0"):
    _status = "disabled by TOPGIMBAL_PURE"
else:
    try:
        _ext = load_extension()
    except ImportError as exc:
        _status = f"not built ({exc})" if "stale" not in str(exc) else str(exc)
    else:
        _status = "enabled"


def enabled() -> bool:
    """True when the C fast path is in use (built, current, and not disabled by TOPGIMBAL_PURE)."""
    return _ext is not None


def status() -> str:
    """Why the fast path is or is not in use, in words."""
    return _status


def parser_methods(
    frame_cls: type, pure: Mapping[str, Callable[..., object]], *, ext: ModuleType | None = None
) -> dict[str, Callable[..., object]] | None:
    """C versions of FrameParser's `feed`, `feed_datagram`, `flush` and `feed_messages` (method
    descriptors: `parser.feed(data)` goes straight into C), or None. `pure` maps each name to the
    pure method it stands for (docs and signature). Rare events go back to the parser's
    `_c_event`, so diagnostics and statistics are the pure parser's. `ext`: an extension from
    `load_extension()` instead of the one in use (tests)."""
    ext = ext or _ext
    if ext is None:
        return None
    return {name: ext.ParserMethod(kind, frame_cls, pure[name]) for kind, name in enumerate(PARSER_METHODS)}


def make_decoder(dialect: Any, message_cls: type, pure: Callable[[Any], Any], *, ext: ModuleType | None = None) -> Any:
    """A Dialect.decode replacement for `dialect` (callable frame -> Message, with
    `.decode_many(frames)`), or None. `pure` is the pure decoder it hands frames to whenever the C
    core is not sure, and whose words every error keeps."""
    ext = ext or _ext
    if ext is None:
        return None
    from .spec import decoder_tables

    return ext.Decoder(
        decoder_tables(dialect.commands.values()),
        message_cls,
        pure,
        dialect.name,
        tuple(dialect.headers),
        dialect.host_addresses,
    )


def make_any_decoder(
    prefer: Any, candidates: Sequence[Any], pure: Callable[[Any], Any], *, ext: ModuleType | None = None
) -> Any:
    """decode_any with a fixed preference: `prefer`'s decoder (or None) first, then the
    `candidates`' (the default dialects' C decoders, in their default order) ranked per frame as
    guess_dialects ranks them; `pure` (the pure decode_any) answers every frame none of them
    decodes natively. None when any of them is not a C decoder."""
    ext = ext or _ext
    if ext is None:
        return None
    decoders = (prefer, *candidates) if prefer is not None else tuple(candidates)
    if not all(isinstance(d, ext.Decoder) for d in decoders):
        return None
    return ext.AnyDecoder(prefer, tuple(candidates), pure)


def recv_many(
    *, ext: ModuleType | None = None
) -> Callable[[int, int], list[tuple[bytes, tuple[str, int] | None]]] | None:
    """`recv_many(fd, max)`: up to `max` (1..64) datagrams waiting on a non-blocking IPv4 UDP socket,
    read in one recvmmsg call, as `[(data, (host, port)), ...]` (`[]` when none waits; an address of
    another family is None); OSError as `recvfrom` raises it. None when the extension is not in use
    or was built where recvmmsg does not exist (not Linux)."""
    ext = ext or _ext
    return None if ext is None else getattr(ext, "recv_many", None)
