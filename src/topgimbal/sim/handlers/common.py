"""Helpers shared by the handler modules."""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

from ...protocol import Message
from ..dispatch import Ctx, Refuse, resolve_write

if TYPE_CHECKING:
    from ..device import Device

# Settings that survive a restart when the simulator has a state file (every stored setting does;
# this set only marks which writes need a flush).
VOLATILE = frozenset({"MNU", "APC", "ATE", "SWH"})


def fields(msg: Message) -> dict[str, Any]:
    if msg.fields is None:
        raise Refuse(msg.error or "malformed")
    return msg.fields


def setting(dev: Device, msg: Message, ctx: Ctx) -> dict[str, Any] | None:
    """A stored setting: a write stores (and is echoed), a query answers what is stored."""
    ident = msg.frame.ident
    store = dev.settings.get(ident)
    if store is None:
        raise Refuse(f"{ident} is not a setting of the {dev.model.name}")
    if msg.frame.rw == "r":
        return dict(store)
    dev.settings[ident] = resolve_write(store, msg)
    if ident not in VOLATILE:
        dev.dirty = True
    return None
