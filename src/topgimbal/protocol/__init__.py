"""The protocol core: frames, the streaming parser, field codecs and the catalog. Standard library
only, no I/O."""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

from .._lazy import lazy_getattr
from .catalog import (
    GROUPS,
    QUERY,
    QUIRKS,
    REQUEST,
    RESPONSE,
    ROLES,
    CommandSpec,
    DeviceModel,
    Dialect,
    Endpoint,
    Form,
    Message,
    VideoStream,
    direction_of,
    factory_values,
)
from .dialects import (
    DIALECT_NAMES,
    all_models,
    any_decoder,
    decode_any,
    dialect_for,
    get_dialect,
    get_model,
    guess_dialects,
)
from .fields import Field
from .frame import Dissection, Frame, checksum, dissect, make_frame, parse_frame

if TYPE_CHECKING:
    from .parser import Diagnostic, FrameParser, ParserStats

# The streaming parser loads on first use (PEP 562): decoding a frame given whole (`topgimbal
# decode FRAME`, `decode()` below) does not need it (docs/architecture.md, "A CLI that starts fast").
__getattr__ = lazy_getattr(__name__, dict.fromkeys(("Diagnostic", "FrameParser", "ParserStats"), "parser"), globals())


def encode(dialect: str | Dialect, ident: str, *, read: bool = False, **values: Any) -> Frame:
    """The request frame for `ident` in `dialect`, fields in user units:
    `encode("skydroid", "GAY", yaw_deg=-50.0, speed_deg_s=5)`."""
    return get_dialect(dialect).encode(ident, read=read, **values)


def decode(dialect: str | Dialect, frame: Frame | bytes | str, *, fallback: bool = True) -> Message:
    """Named fields of a frame (bytes and text are parsed strictly first). With `fallback`, a frame
    `dialect` cannot decode is tried with the other dialect; `Message.dialect` says which one did."""
    if not isinstance(frame, Frame):
        frame = parse_frame(frame if isinstance(frame, bytes) else frame.encode("latin-1"))
    if fallback:
        return decode_any(frame, prefer=dialect)
    return get_dialect(dialect).decode(frame)


__all__ = [
    "DIALECT_NAMES",
    "GROUPS",
    "QUERY",
    "QUIRKS",
    "REQUEST",
    "RESPONSE",
    "ROLES",
    "CommandSpec",
    "DeviceModel",
    "Diagnostic",
    "Dialect",
    "Dissection",
    "Endpoint",
    "Field",
    "Form",
    "Frame",
    "FrameParser",
    "Message",
    "ParserStats",
    "VideoStream",
    "all_models",
    "any_decoder",
    "checksum",
    "decode",
    "decode_any",
    "dialect_for",
    "direction_of",
    "dissect",
    "encode",
    "factory_values",
    "get_dialect",
    "get_model",
    "guess_dialects",
    "make_frame",
    "parse_frame",
]
