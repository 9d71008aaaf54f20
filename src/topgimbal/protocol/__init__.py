"""The protocol core: frames, the streaming parser, field codecs and the catalog. Standard library
only, no I/O."""

from __future__ import annotations

from typing import Any

from .catalog import REQUEST, RESPONSE, CommandSpec, DeviceModel, Dialect, Endpoint, Form, Message, direction_of
from .dialects import DIALECT_NAMES, all_models, get_dialect, get_model
from .fields import Field
from .frame import Dissection, Frame, checksum, dissect, make_frame, parse_frame
from .parser import Diagnostic, FrameParser, ParserStats


def encode(dialect: str | Dialect, ident: str, *, read: bool = False, **values: Any) -> Frame:
    """The request frame for `ident` in `dialect`, fields in user units:
    `encode("skydroid", "GAY", yaw_deg=-50.0, speed_deg_s=5)`."""
    return get_dialect(dialect).encode(ident, read=read, **values)


def decode(dialect: str | Dialect, frame: Frame | bytes | str) -> Message:
    """Named fields of a frame (bytes and text are parsed strictly first)."""
    if not isinstance(frame, Frame):
        frame = parse_frame(frame if isinstance(frame, bytes) else frame.encode("latin-1"))
    return get_dialect(dialect).decode(frame)


__all__ = [
    "DIALECT_NAMES",
    "REQUEST",
    "RESPONSE",
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
    "all_models",
    "checksum",
    "decode",
    "direction_of",
    "dissect",
    "encode",
    "get_dialect",
    "get_model",
    "make_frame",
    "parse_frame",
]
