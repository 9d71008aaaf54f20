"""MAVLink bridge: a TOP camera as standard MAVLink gimbal (protocol v2, device and manager
roles) and camera (protocol v2) components. Needs the `mavlink` extra (pymavlink).

    from topgimbal.mavlink import Bridge, BridgeConfig
    async with Bridge(BridgeConfig(url="udp://127.0.0.1:5000", model="C12",
                                   endpoints=["udpout:127.0.0.1:14550"])) as bridge:
        await bridge.wait_closed()
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from .._lazy import lazy_getattr

if TYPE_CHECKING:
    from ..links.endpoints import EndpointError, parse_endpoint
    from ..links.mav import MavlinkUnavailableError
    from .bridge import ROLES, Bridge, BridgeConfig, BridgeConfigError

# Lazy (PEP 562): `topgimbal mavlink`'s flags come from features/ without loading the bridge
_LAZY = {
    "MavlinkUnavailableError": "topgimbal.links.mav",
    "ROLES": "bridge",
    "Bridge": "bridge",
    "BridgeConfig": "bridge",
    "BridgeConfigError": "bridge",
    "EndpointError": "topgimbal.links.endpoints",
    "parse_endpoint": "topgimbal.links.endpoints",
}

__getattr__ = lazy_getattr(__name__, _LAZY, globals())

__all__ = [
    "ROLES",
    "Bridge",
    "BridgeConfig",
    "BridgeConfigError",
    "EndpointError",
    "MavlinkUnavailableError",
    "parse_endpoint",
]
