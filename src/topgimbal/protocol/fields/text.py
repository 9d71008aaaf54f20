"""Text codecs: free text, dotted IPv4 addresses, raw bytes given as hex, fixed literals.

Nothing a caller types can end a frame early or start a second one: text is printable ASCII without
`#`, and raw bytes refuse `#`, CR and LF unless the codec is binary by definition."""

from __future__ import annotations

import ipaddress
from dataclasses import dataclass, field
from typing import ClassVar

from ...errors import FieldValueError
from .base import Codec

# Bytes that delimit frames on a stream: a value must not contain them.
FRAME_BYTES = frozenset(b"#\r\n")


def printable_text(value: str) -> bool:
    """Printable ASCII (space included) without `#`: what a text field may put on the wire."""
    return value.isascii() and value.isprintable() and "#" not in value


@dataclass(frozen=True)
class Text(Codec):
    """Printable ASCII text of `min_len`..`max_len` characters (versions, model names); `#` is
    refused (it starts a frame)."""

    min_len: int = 1
    max_len: int = 15
    kind: ClassVar[str] = "text"

    @property
    def min_width(self) -> int:
        return self.min_len

    @property
    def max_width(self) -> int:
        return self.max_len

    def allowed(self) -> str:
        return f"printable ASCII text of {self.min_len}..{self.max_len} characters, without '#'"

    def encode(self, value: object, name: str = "value") -> bytes:
        if not isinstance(value, str) or not self.min_len <= len(value) <= self.max_len or not printable_text(value):
            raise FieldValueError(name, value, self.allowed())
        return value.encode("ascii")

    def decode(self, raw: bytes) -> str:
        if not self.min_len <= len(raw) <= self.max_len:
            raise ValueError(f"{len(raw)} characters, expected {self.min_len}..{self.max_len}")
        return raw.decode("latin-1")

    def neutral(self) -> str:
        return "0" * max(self.min_len, 1)


@dataclass(frozen=True)
class IPv4Text(Codec):
    """A dotted IPv4 address as text (`192.168.31.22`)."""

    kind: ClassVar[str] = "ipv4"

    @property
    def min_width(self) -> int:
        return 7

    @property
    def max_width(self) -> int:
        return 15

    def allowed(self) -> str:
        return "a dotted IPv4 address (a.b.c.d, each 0..255)"

    def encode(self, value: object, name: str = "value") -> bytes:
        if not isinstance(value, (str, ipaddress.IPv4Address)) or (isinstance(value, str) and len(value) > 15):
            raise FieldValueError(name, value, self.allowed())
        try:
            addr = ipaddress.IPv4Address(value if isinstance(value, ipaddress.IPv4Address) else value.strip())
            return str(addr).encode("ascii")
        except ValueError:
            raise FieldValueError(name, value, self.allowed()) from None

    def decode(self, raw: bytes) -> str:
        return str(ipaddress.IPv4Address(raw.decode("ascii")))

    def neutral(self) -> str:
        return "0.0.0.0"


@dataclass(frozen=True)
class RawData(Codec):
    """Bytes whose layout the documents do not give; shown and entered as hex. Unless `binary`
    (packed structs), `#`, CR and LF are refused: they would split the frame on a stream."""

    width: int | None = None
    binary: bool = False
    max_bytes: int = 0xFF  # variable width: the most a frame of the dialect can carry
    min_bytes: int = 0  # variable width: the fewest (1 where an empty tail would be another form)
    kind: ClassVar[str] = "raw"

    @property
    def min_width(self) -> int:
        return self.width if self.width is not None else self.min_bytes

    @property
    def max_width(self) -> int:
        return self.width if self.width is not None else self.max_bytes

    def allowed(self) -> str:
        n = f"{self.width} bytes" if self.width is not None else f"{self.min_bytes}..{self.max_bytes} bytes"
        return f"{n} given as a hex string" + ("" if self.binary else " (no 23 '#', 0D or 0A)")

    def encode(self, value: object, name: str = "value") -> bytes:
        if isinstance(value, (bytes, bytearray)):
            data = bytes(value)
        elif isinstance(value, str) and len(value) <= 2 * self.max_width + 1:
            try:
                data = bytes.fromhex(value)
            except ValueError:
                raise FieldValueError(name, value, self.allowed()) from None
        else:
            raise FieldValueError(name, value, self.allowed())
        if not self.min_width <= len(data) <= self.max_width or (not self.binary and FRAME_BYTES.intersection(data)):
            raise FieldValueError(name, value, self.allowed())
        return data

    def decode(self, raw: bytes) -> str:
        if self.width is not None and len(raw) != self.width:
            raise ValueError(f"{len(raw)} bytes where {self.width} are needed")
        return raw.hex()

    def neutral(self) -> str:
        return "00" * (self.width or 1)


@dataclass(frozen=True)
class Literal(Codec):
    """Fixed data (the error frame's `!!`); decodes to itself."""

    text: str = "!!"
    kind: ClassVar[str] = "literal"
    width: int | None = field(init=False, default=None)

    def __post_init__(self) -> None:
        object.__setattr__(self, "width", len(self.text))

    def allowed(self) -> str:
        return f"exactly {self.text!r}"

    def encode(self, value: object, name: str = "value") -> bytes:
        if value is not None and value != self.text:
            raise FieldValueError(name, value, self.allowed())
        return self.text.encode("latin-1")

    def decode(self, raw: bytes) -> str:
        if raw != self.text.encode("latin-1"):
            raise ValueError(f"{raw!r} is not {self.text!r}")
        return self.text

    def neutral(self) -> str:
        return self.text


__all__ = ["FRAME_BYTES", "IPv4Text", "Literal", "RawData", "Text", "printable_text"]
