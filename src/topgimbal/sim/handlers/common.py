"""What several handlers share: a request's fields, and stored settings (a write stores, a query
answers what is stored), with relative steps and "keep" values read from the catalog's enums."""

from __future__ import annotations

from typing import Any

from ...protocol import Message
from ...protocol.commands import stored_form
from ...protocol.fields import Codec, Enum, OneOf
from ...protocol.fields.enums import KEEP_NAMES
from ..context import RefusedError, Request, SimState

# Enum values that step relative to the current value rather than being values themselves.
RELATIVE = {"next": 1, "previous": -1, "awb_plus": 1, "awb_minus": -1, "toggle": 1}
# Settings that do not survive a reboot: a write to them does not touch the state file.
VOLATILE_ROLES = frozenset({"menu", "aperture", "factory_test", "aux_power"})


def fields(msg: Message) -> dict[str, Any]:
    if msg.fields is None:
        raise RefusedError(msg.error or "malformed")
    return msg.fields


def _enum(codec: Codec) -> Enum | None:
    codec = codec.tokens if isinstance(codec, OneOf) else codec
    return codec if isinstance(codec, Enum) else None


def resolve_write(current: dict[str, Any], msg: Message) -> dict[str, Any]:
    """The stored values after a write: relative steps applied, `null` keeps the old value, and
    only the fields the setting stores (a 4-character IMG's channel is not a setting)."""
    assert msg.fields is not None and msg.form is not None
    new = dict(current)
    for f in msg.form.fields:
        if f.name not in current:
            continue
        v = msg.fields.get(f.name)
        enum = _enum(f.codec)
        if isinstance(v, str) and v in KEEP_NAMES:
            continue
        if enum is not None and isinstance(v, str) and v in RELATIVE:
            plain = [x.name for x in enum.plain_values()]
            if plain:
                cur = current.get(f.name, plain[0])
                i = plain.index(cur) if cur in plain else 0
                new[f.name] = plain[(i + RELATIVE[v]) % len(plain)]
            continue
        new[f.name] = v
    return new


def setting(state: SimState, msg: Message, req: Request) -> dict[str, Any] | None:
    """A stored setting: a write stores (and is echoed), a query answers what is stored."""
    spec = msg.spec
    assert spec is not None
    store = state.settings.get(spec.ident)
    if store is None:
        if stored_form(spec) is None:
            raise RefusedError(f"{spec.ident} stores nothing")
        store = state.settings[spec.ident] = {}
    if req.frame.rw == "r":
        return dict(store)
    state.settings[spec.ident] = resolve_write(store, msg) if store else dict(fields(msg))
    if spec.role not in VOLATILE_ROLES:
        state.dirty = True
    return None


def refuse(state: SimState, msg: Message, req: Request) -> None:
    raise RefusedError(f"{req.frame.ident} is not something a host sends")


__all__ = ["RELATIVE", "fields", "refuse", "resolve_write", "setting"]
