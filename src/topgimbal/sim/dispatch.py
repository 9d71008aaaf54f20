"""The handler table: identifier -> function of the decoded request.

A handler receives the device, the decoded `Message` (fields in user units and in the API sign
convention: the device maps wire signs both ways) and a `Ctx`; it changes the device state and
returns what to answer (values in the API convention too):

- `None`: echo the request with swapped addresses (the protocol's rule for control commands);
- a dict: field values for `dialect.response(request, **values)` (a query's answer, or a write
  whose reply carries more than the echo, such as TOPOTEK REC / CAP file indexes);
- `Reply(...)`: values with another control character, or `Reply(send=False)` for no answer.

A handler raises `Refuse` for a request the device cannot carry out; the device answers it with the
error frame. Frames a handler wants sent after its reply (ZMP, LRF results) go to `ctx.notify`.
"""

from __future__ import annotations

from collections.abc import Callable, Hashable
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any, Union

from ..protocol import Frame, Message
from ..protocol.fields import DecFloat, DecInt, Enum, HexInt, IPv4Text, OneOf, RawData, Text

if TYPE_CHECKING:
    from .device import Device


class Refuse(Exception):
    """The device cannot do this: answer with the error frame."""


@dataclass
class Reply:
    values: dict[str, Any] | None = None
    rw: str | None = None
    send: bool = True


@dataclass
class Ctx:
    peer: Hashable
    frame: Frame
    now: float
    notes: list[Frame] = field(default_factory=list)

    @property
    def host(self) -> str:
        """The host's address letter (U or P): where replies and streams are addressed."""
        return self.frame.src

    def notify(self, frame: Frame) -> None:
        self.notes.append(frame)


Result = Union[None, dict[str, Any], Reply]  # noqa: UP007  (a runtime alias: py3.10 syntax limits)
Handler = Callable[["Device", Message, Ctx], Result]
HANDLERS: dict[str, Handler] = {}


def handles(*idents: str) -> Callable[[Handler], Handler]:
    def deco(fn: Handler) -> Handler:
        for ident in idents:
            if ident in HANDLERS:
                raise ValueError(f"{ident} has two handlers")
            HANDLERS[ident] = fn
        return fn

    return deco


# -- generic stored settings -------------------------------------------------------------------------

# Enum values that are steps relative to the current value rather than values themselves.
RELATIVE = {"next": 1, "previous": -1, "awb_plus": 1, "awb_minus": -1}
KEEP = {"null"}

# Sensible factory values where the first table entry would be odd; anything not named here
# defaults to the first plain value of its field's table, or the low end of its range.
DEFAULTS: dict[str, dict[str, Any]] = {
    "IMG": {"palette": "white_hot"},
    "IQE": {"style": "standard", "hue": 128, "brightness": 128, "saturation": 128, "contrast": 128, "sharpness": 128},
    "VOM": {"fps": 30, "gop": 30, "bitrate_kbps": 4000, "output": "on"},
    "EXT": {"osd": "on", "led": "off"},
    "VID": {"primary": "1080p", "resolution": "1920x1080"},
    "BIT": {"bitrate_kbps": 4000},
    "TAS": {"interval_s": 10},
    "TDI": {"detail": 50},
    "TIB": {"brightness": 50},
    "TIC": {"contrast": 50},
    "TAR": {"spatial_denoise": 50},
    "TTR": {"temporal_denoise": 50},
    "TGM": {"gamma": 50},
    "EVS": {"data": "00"},
}


def plain_values(codec: Enum) -> list[str]:
    return [v.name for v in codec.values if v.name not in RELATIVE and v.name not in KEEP and v.idempotent]


def default_value(codec: Any) -> Any:
    if isinstance(codec, Enum):
        plain = plain_values(codec)
        return plain[0] if plain else codec.values[0].name
    if isinstance(codec, OneOf):
        return default_value(codec.number)
    if isinstance(codec, (HexInt, DecInt, DecFloat)):
        lo = codec.min if codec.min is not None else 0
        hi = codec.max if codec.max is not None else 0
        return max(lo, min(hi, 0))
    if isinstance(codec, IPv4Text):
        return "0.0.0.0"
    if isinstance(codec, RawData):
        return "00" * (codec.width or 1)
    if isinstance(codec, Text):
        return "0" * codec.min_len
    return None


def resolve_write(current: dict[str, Any], msg: Message) -> dict[str, Any]:
    """The stored values after a write: relative steps applied, `null` keeps the old value."""
    assert msg.fields is not None and msg.form is not None
    new = dict(current)
    for f in msg.form.fields:
        v = msg.fields.get(f.name)
        codec = f.codec.tokens if isinstance(f.codec, OneOf) else f.codec
        if isinstance(v, str) and v in KEEP:
            continue
        if isinstance(codec, Enum) and isinstance(v, str) and (v in RELATIVE or v == "toggle"):
            plain = plain_values(codec)
            if plain:
                cur = current.get(f.name, plain[0])
                i = plain.index(cur) if cur in plain else 0
                new[f.name] = plain[(i + (RELATIVE.get(v, 1))) % len(plain)]
            continue
        new[f.name] = v
    return new
