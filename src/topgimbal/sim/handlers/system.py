"""Network settings and resets. Addresses are stored, answered and persisted; the simulator never
binds them (it only ever listens where it was told to, loopback by default). Which address a
command sets comes from its field's state key (`network.ip` -> `NetworkState.ip`)."""

from __future__ import annotations

from typing import Any

from ...protocol import Message
from ..context import RefusedError, Request, SimState
from ..state import NETWORK_KEY, NetworkState
from .common import fields


def _attribute(msg: Message) -> str:
    assert msg.spec is not None
    key = msg.spec.state_keys.get("address", "")
    if not key.startswith(NETWORK_KEY) or key[len(NETWORK_KEY) :] not in NetworkState.__dataclass_fields__:
        raise RefusedError(f"{msg.spec.ident} names no network setting")
    return key[len(NETWORK_KEY) :]


def address(state: SimState, msg: Message, req: Request) -> dict[str, Any] | None:
    attr = _attribute(msg)
    if req.frame.rw == "r":
        return {"address": getattr(state.network, attr)}
    setattr(state.network, attr, fields(msg)["address"])
    state.dirty = True
    return None


def network_reset(state: SimState, msg: Message, req: Request) -> None:
    """01 resets the network settings; 00 (sent by some clients, meaning undocumented) keeps them."""
    if fields(msg)["action"] == "reset":
        state.network = NetworkState()
        state.dirty = True


def reboot(state: SimState, msg: Message, req: Request) -> None:
    """00 reboot: motion, streams and recording stop; 01 factory reset: settings too."""
    state.reboots += 1
    state.camera.recording = False
    state.streams.clear()
    state.gimbal.center()
    if fields(msg)["action"] == "factory_reset":
        state.factory_reset()
