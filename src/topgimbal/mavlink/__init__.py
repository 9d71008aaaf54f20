"""MAVLink bridge: a TOP camera as standard MAVLink gimbal (protocol v2, device and manager
roles) and camera (protocol v2) components. Needs the `mavlink` extra (pymavlink).

    from topgimbal.mavlink import Bridge, BridgeConfig
    async with Bridge(BridgeConfig(url="udp://127.0.0.1:5000", model="C12",
                                   endpoints=["udpout:127.0.0.1:14550"])) as bridge:
        await bridge.wait_closed()
"""

from __future__ import annotations

from ._mav import MavlinkUnavailableError
from .bridge import ROLES, Bridge, BridgeConfig, BridgeConfigError
from .endpoints import EndpointError, parse_endpoint

__all__ = [
    "ROLES",
    "Bridge",
    "BridgeConfig",
    "BridgeConfigError",
    "EndpointError",
    "MavlinkUnavailableError",
    "parse_endpoint",
]
