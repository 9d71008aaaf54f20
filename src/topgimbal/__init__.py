"""topgimbal: both ends of the TOP gimbal-camera protocol (TOPOTEK SIP, SkyDroid C10..C20)."""

from __future__ import annotations

from ._speedups import enabled as speedups_enabled
from .client import AsyncClient, Gimbal, connect
from .errors import (
    CatalogError,
    ChecksumError,
    DeviceError,
    FieldValueError,
    FrameError,
    LengthError,
    RequestTimeoutError,
    TopGimbalError,
    TransportError,
    UnknownCommandError,
    UnsupportedError,
)
from .protocol import (
    DeviceModel,
    Diagnostic,
    Dialect,
    Frame,
    FrameParser,
    Message,
    decode,
    encode,
    get_dialect,
    get_model,
    parse_frame,
)

__version__ = "0.1.0"

__all__ = [
    "AsyncClient",
    "CatalogError",
    "ChecksumError",
    "DeviceError",
    "DeviceModel",
    "Diagnostic",
    "Dialect",
    "FieldValueError",
    "Frame",
    "FrameError",
    "FrameParser",
    "Gimbal",
    "LengthError",
    "Message",
    "RequestTimeoutError",
    "TopGimbalError",
    "TransportError",
    "UnknownCommandError",
    "UnsupportedError",
    "__version__",
    "connect",
    "decode",
    "encode",
    "get_dialect",
    "get_model",
    "parse_frame",
    "speedups_enabled",
]
