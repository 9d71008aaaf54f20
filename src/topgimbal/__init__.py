"""topgimbal: both ends of the TOP gimbal-camera protocol (TOPOTEK SIP, SkyDroid C10..C20)."""

from __future__ import annotations

from typing import TYPE_CHECKING

from . import _moved
from .errors import (
    CatalogError,
    ChecksumError,
    DeviceError,
    FieldValueError,
    FrameError,
    LengthError,
    LinkLostError,
    ModelMismatchError,
    NoAnswerError,
    RequestTimeoutError,
    TopGimbalError,
    TransportError,
    UnknownCommandError,
    UnsupportedError,
)

if TYPE_CHECKING:
    from ._speedups import enabled as speedups_enabled
    from .client import AsyncClient, Gimbal, connect
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

_moved.install()  # old import paths of modules that moved (_moved.MOVED)

# The protocol core and the client load on first use (PEP 562): `import topgimbal.protocol` does not
# load the client (asyncio, the typed methods), and `topgimbal --help` loads neither
# (docs/architecture.md, "A CLI that starts fast").
_LAZY = {
    **dict.fromkeys(("AsyncClient", "Gimbal", "connect"), "client"),
    **dict.fromkeys(
        ("DeviceModel", "Diagnostic", "Dialect", "Frame", "FrameParser", "Message", "decode", "encode",
         "get_dialect", "get_model", "parse_frame"),
        "protocol",
    ),
    "speedups_enabled": "_speedups",
}  # fmt: skip
_ATTR = {"speedups_enabled": "enabled"}


def __getattr__(name: str) -> object:
    if name in _LAZY:
        import importlib

        value = getattr(importlib.import_module(f".{_LAZY[name]}", __name__), _ATTR.get(name, name))
        globals()[name] = value
        return value
    import importlib.util

    if not name.startswith("_") and importlib.util.find_spec(f"{__name__}.{name}") is not None:
        return importlib.import_module(f".{name}", __name__)  # a submodule, as eager imports made it one
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")


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
    "LinkLostError",
    "Message",
    "ModelMismatchError",
    "NoAnswerError",
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
