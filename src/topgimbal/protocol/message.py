"""A decoded frame, and which direction a frame travels."""

from __future__ import annotations

from collections.abc import Callable
from operator import itemgetter
from typing import Any, NamedTuple

from .commands import CommandSpec
from .forms import REQUEST, RESPONSE, Form
from .frame import DEVICE_ADDRESSES, HOST_ADDRESSES, Frame


class LazyText:
    """Text built when first read: an error path stays cheap for the frames nobody asks about (a
    capture of unusual traffic decodes every frame; few errors are ever shown), and reads the same
    as the eager string it replaces. Equal to that string, hashed as it, str() and repr() of it."""

    __slots__ = ("_make", "_text")

    def __init__(self, make: Callable[[], str]) -> None:
        self._make: Callable[[], str] | None = make
        self._text: str | None = None

    def __str__(self) -> str:
        if self._text is None:
            assert self._make is not None
            self._text, self._make = self._make(), None
        return self._text

    def __repr__(self) -> str:
        return repr(str(self))

    def __eq__(self, other: object) -> bool:
        if isinstance(other, (str, LazyText)):
            return str(self) == str(other)
        return NotImplemented

    def __hash__(self) -> int:
        return hash(str(self))


class _MessageTuple(NamedTuple):
    frame: Frame
    spec: CommandSpec | None
    form: Form | None
    fields: dict[str, Any] | None
    error: str | LazyText | None = None
    dialect: str | None = None


_error_slot = itemgetter(4)  # the tuple's own position of `error` (the property below reads it)


class Message(_MessageTuple):
    """A decoded frame: the spec and form it matched and its fields in user units.

    `fields` is None (and `error` says why) when the identifier is unknown or the data fit no form.
    `dialect` names the dialect that decoded it (with cross-dialect fallback it may differ from the
    one first asked). A tuple, because the parser and decoder build one per frame on the hot path;
    new fields are only ever appended, so positional construction keeps working. `error` is always
    read as a str (or None); a decoder may store a LazyText there, worded only when read."""

    __slots__ = ()

    @property
    def error(self) -> str | None:
        e = _error_slot(self)
        return e if e is None or e.__class__ is str else str(e)

    def __repr__(self) -> str:
        """Short, as pymavlink's messages print: identifier, name, fields (or the error), frame."""
        name = f" {self.spec.name}" if self.spec is not None else ""
        what = f"fields={self.fields!r}" if self.fields is not None else f"error={self.error!r}"
        return f"<Message {self.frame.ident}{name} {what} frame={self.frame.text()!r}>"

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


__all__ = ["LazyText", "Message", "direction_of"]
