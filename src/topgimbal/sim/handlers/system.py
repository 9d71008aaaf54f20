"""Network settings and resets. Addresses are stored, answered and persisted; the simulator never
binds them (it only ever listens where it was told to, loopback by default)."""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

from ...protocol import Message
from ..dispatch import Ctx, handles
from ..state import NetworkState
from .common import fields

if TYPE_CHECKING:
    from ..device import Device

NETWORK = {"IPV": "ip", "GTW": "gateway", "DNS": "dns", "BNS": "backup_dns"}


@handles(*NETWORK)
def address(dev: Device, msg: Message, ctx: Ctx) -> dict[str, Any] | None:
    attr = NETWORK[msg.frame.ident]
    if msg.frame.rw == "r":
        return {"address": getattr(dev.network, attr)}
    setattr(dev.network, attr, fields(msg)["address"])
    dev.dirty = True
    return None


@handles("RST")
def rst(dev: Device, msg: Message, ctx: Ctx) -> None:
    dev.network = NetworkState()
    dev.dirty = True


@handles("RTF")
def rtf(dev: Device, msg: Message, ctx: Ctx) -> None:
    """00 reboot: motion, streams and recording stop; 01 factory reset: settings too."""
    dev.reboots += 1
    dev.camera.recording = False
    dev.streams.clear()
    dev.gimbal.center()
    if fields(msg)["action"] == "factory_reset":
        dev.factory_reset()
