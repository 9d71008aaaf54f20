"""A decoded frame, and which direction a frame travels."""

from __future__ import annotations

from typing import Any, NamedTuple

from .commands import CommandSpec
from .forms import REQUEST, RESPONSE, Form
from .frame import DEVICE_ADDRESSES, HOST_ADDRESSES, Frame


class Message(NamedTuple):
    """A decoded frame: the spec and form it matched and its fields in user units.

    `fields` is None (and `error` says why) when the identifier is unknown or the data fit no form.
    `dialect` names the dialect that decoded it (with cross-dialect fallback it may differ from the
    one first asked). A tuple, because the parser and decoder build one per frame on the hot path;
    new fields are only ever appended, so positional construction keeps working."""

    frame: Frame
    spec: CommandSpec | None
    form: Form | None
    fields: dict[str, Any] | None
    error: str | None = None
    dialect: str | None = None

    @property
    def ident(self) -> str:
        return self.frame.ident

    @property
    def is_error(self) -> bool:
        return self.frame.ident == "ERE"

    @property
    def ok(self) -> bool:
        return self.fields is not None

    def to_dict(self) -> dict[str, Any]:
        fields = None
        if self.fields is not None and self.form is not None:
            codecs = {f.name: f.codec for f in self.form.fields}
            fields = {k: (codecs[k].to_json(v) if k in codecs else v) for k, v in self.fields.items()}
        return {
            "id": self.frame.ident,
            "name": self.spec.name if self.spec else None,
            "rw": self.frame.rw,
            "src": self.frame.src,
            "dst": self.frame.dst,
            "fields": fields,
            "error": self.error,
            "dialect": self.dialect,
        }


def direction_of(frame: Frame) -> str:
    """`response` for device -> host frames, `request` otherwise."""
    return RESPONSE if frame.src in DEVICE_ADDRESSES and frame.dst in HOST_ADDRESSES else REQUEST


__all__ = ["Message", "direction_of"]
