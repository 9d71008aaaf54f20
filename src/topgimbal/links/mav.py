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


# Ids and enum values by name: the bridge writes no MAVLink number itself, so a command or message
# id can be read (and grepped) as the name the spec gives it, and is pymavlink's, not a copy.
# Without pymavlink every one is `NOT_LOADED`: the modules still import (the CLI's help, the
# docs), and nothing can use the value, since sending or parsing calls `mavlink()`, which raises.
NOT_LOADED = -1


def mav_id(name: str) -> int:
    """An enum value of pymavlink's common dialect by its full name (`MAV_CMD_REQUEST_MESSAGE`,
    `MAV_TYPE_GIMBAL`, `MAV_COMP_ID_CAMERA`); a name the dialect lacks is an AttributeError at import."""
    return NOT_LOADED if _common is None else int(getattr(_common, name))


def msg_id(name: str) -> int:
    """A message's id by its name (`CAMERA_INFORMATION`: pymavlink's `MAVLINK_MSG_ID_CAMERA_INFORMATION`)."""
    return mav_id(f"MAVLINK_MSG_ID_{name}")


__all__ = ["MAVLinkCodec", "MAVLinkMessage", "MavlinkUnavailableError", "available", "mav_id", "mavlink", "msg_id"]
