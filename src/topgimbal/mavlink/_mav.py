"""The one place that imports pymavlink (an optional extra: `pip install 'topgimbal[mavlink]'`).

We use the generated MAVLink 2 common dialect module directly, never `mavutil`: mavutil picks a
global dialect from the environment (MAVLINK20, set_dialect) and does blocking I/O; the generated
module is pure encode/decode, which is all the bridge needs."""

from __future__ import annotations

from types import ModuleType
from typing import TYPE_CHECKING

from ..errors import TopGimbalError


class MavlinkUnavailableError(TopGimbalError):
    """pymavlink is not installed."""


if TYPE_CHECKING:
    # The types of what pymavlink builds and parses (for annotations; imported at run time by
    # nobody but `mavlink()`): MAVLinkMessage has `get_type()`, `get_srcSystem()` and the fields,
    # MAVLinkCodec is the encoder / parser object.
    from pymavlink.dialects.v20.common import MAVLink as MAVLinkCodec
    from pymavlink.dialects.v20.common import MAVLink_message as MAVLinkMessage

try:
    from pymavlink.dialects.v20 import common as _common
except ImportError:  # pragma: no cover - depends on the installation
    _common = None


def mavlink() -> ModuleType:
    """The pymavlink common dialect module (MAVLink 2); raises with what to install."""
    if _common is None:
        raise MavlinkUnavailableError("the MAVLink bridge needs pymavlink: pip install 'topgimbal[mavlink]'")
    return _common


def available() -> bool:
    return _common is not None


__all__ = ["MAVLinkCodec", "MAVLinkMessage", "MavlinkUnavailableError", "available", "mavlink"]
