"""What the page can ask for over the WebSocket, mapped onto the client SDK.

Every op gets exactly one answer: `ack` (with a result) or `error` (with a readable message).
The console never talks to the camera except through the client (`AsyncClient`)."""

from __future__ import annotations

import asyncio
import math
from collections.abc import Awaitable, Callable, Mapping

from ..client import CameraAPI
from ..client.jsonable import JsonValue, jsonable
from ..errors import (
    DeviceError,
    FieldValueError,
    FrameError,
    RequestTimeoutError,
    TopGimbalError,
    TransportError,
    UnknownCommandError,
    UnsupportedError,
)
from ..protocol import Message
from ..protocol.frame import complete_frame

# What the page gets back: JSON, by the SDK's one encoding (client/jsonable.py; NaN is null).
# An op's arguments are the page's JSON object, unchecked until the op reads them; its result any
# client result, made JSON by `jsonable`.
OpArgs = Mapping[str, object]
OpHandler = Callable[[CameraAPI, OpArgs], Awaitable[object]]
SdStatus = dict[str, bool | int | None]  # op_sd: present, remaining_mb, total_mb


class OpError(TopGimbalError, ValueError):
    """A malformed op from the page (missing or wrong argument)."""


class ReadOnlyError(TopGimbalError):
    """The console only watches (a proxy's traffic): it sends nothing to the camera."""


def short(value: object, limit: int = 40, *, quote: bool = True) -> str:
    """`value` for an error message, cut to `limit` characters (a page may send anything)."""
    text = repr(value) if quote else str(value)
    return text if len(text) <= limit else f"{text[: limit - 1]}…"


# What an exception raised by an op tells the page: (types, kind, message, text when the exception
# carries none). The first match wins, so subclasses come before their bases.
ERROR_KINDS: tuple[tuple[type[BaseException] | tuple[type[BaseException], ...], str, str, str], ...] = (
    (DeviceError, "device", "The camera refused {what}: {detail}", "it answered with its error frame (ERE)"),
    ((RequestTimeoutError, asyncio.TimeoutError), "timeout", "No answer from the camera to {what}: {detail}",
     "timed out"),
    (FieldValueError, "value", "Invalid value for {what}: {detail}", ""),
    (UnsupportedError, "unsupported", "Not supported ({what}): {detail}", ""),
    (UnknownCommandError, "unknown", "{detail}", ""),
    (FrameError, "frame", "Not a valid frame: {detail}", ""),
    (TransportError, "link", "Link error during {what}: {detail}", ""),
    (OpError, "op", "{detail}", ""),
    (ReadOnlyError, "readonly", "Not sent ({what}): {detail}", ""),
    (TopGimbalError, "error", "{what}: {detail}", ""),
    ((TypeError, ValueError), "value", "Invalid arguments for {what}: {detail}", ""),
)  # fmt: skip


def describe_error(exc: BaseException, what: str = "") -> tuple[str, str]:
    """(kind, readable message) for an exception raised while carrying out an op on `what`."""
    what = what or "the command"
    for types, kind, message, default in ERROR_KINDS:
        if isinstance(exc, types):
            return kind, message.format(what=what, detail=str(exc) or default)
    return "internal", f"{what} failed: {type(exc).__name__}: {exc}"


def _num(args: OpArgs, name: str, *, required: bool = True) -> float | None:
    if name not in args or args[name] in (None, ""):
        if required:
            raise OpError(f"missing number {name!r}")
        return None
    given = args[name]
    try:
        if not isinstance(given, (int, float, str)):
            raise TypeError(given)
        v = float(given)
    except (TypeError, ValueError):
        raise OpError(f"{name}={short(given)} is not a number") from None
    if not math.isfinite(v):
        raise OpError(f"{name}={short(args[name])} is not a finite number")
    return v


def _text(args: OpArgs, name: str) -> str:
    v = args.get(name)
    if not isinstance(v, str) or not v:
        raise OpError(f"missing text {name!r}")
    return v


def _flag(args: OpArgs, name: str) -> bool:
    v = args.get(name, False)
    if v is None:
        return False
    if not isinstance(v, bool):
        raise OpError(f"{name}={short(v)}: expected true or false")
    return v


async def op_request(cam: CameraAPI, args: OpArgs) -> Message:
    ident = _text(args, "id")
    values = args.get("values") or {}
    if not isinstance(values, Mapping):
        raise OpError("values must be an object of field names to values")
    return await cam.request(ident, read=_flag(args, "read"), **dict(values))


async def op_raw(cam: CameraAPI, args: OpArgs) -> dict[str, JsonValue]:
    """Send a hand-typed frame (its checksum appended when missing); answer with the reply's
    fields and the frame actually sent."""
    sent = complete_frame(_text(args, "frame"))
    reply = jsonable(await cam.send_raw(sent))
    out = reply if isinstance(reply, dict) else {"id": None, "fields": None}
    return {**out, "sent": sent.decode("latin-1")}


async def op_point(cam: CameraAPI, args: OpArgs) -> None:
    yaw = _num(args, "yaw", required=False)
    pitch = _num(args, "pitch", required=False)
    if yaw is None and pitch is None:
        raise OpError("give a yaw and/or a pitch angle")
    return await cam.set_angles(yaw_deg=yaw, pitch_deg=pitch)


async def op_rates(cam: CameraAPI, args: OpArgs) -> None:
    return await cam.rates(yaw_deg_s=_num(args, "yaw") or 0.0, pitch_deg_s=_num(args, "pitch") or 0.0)


async def op_stop(cam: CameraAPI, args: OpArgs) -> None:
    return await cam.stop()


async def op_center(cam: CameraAPI, args: OpArgs) -> None:
    return await cam.center()


async def op_mode(cam: CameraAPI, args: OpArgs) -> None:
    mode = _text(args, "mode")
    if mode not in ("follow", "lock"):
        raise OpError(f"mode={short(mode)}: expected follow or lock")
    return await cam.set_mode(mode)


async def op_ptz(cam: CameraAPI, args: OpArgs) -> Message:
    """A gimbal control code (calibrations, mount orientation, trims) by its catalog name."""
    action = _text(args, "action")
    spec = cam.dialect.require_role("gimbal_control", cam.model)
    return await cam.request(spec.ident, action=action)


async def op_photo(cam: CameraAPI, args: OpArgs) -> Message:
    return await cam.photo()


async def op_record(cam: CameraAPI, args: OpArgs) -> None:
    action = _text(args, "action")
    if action == "start":
        return await cam.start_recording()
    if action == "stop":
        return await cam.stop_recording()
    raise OpError(f"action={short(action)}: expected start or stop")


async def op_recording(cam: CameraAPI, args: OpArgs) -> bool:
    return await cam.recording()


async def op_sd(cam: CameraAPI, args: OpArgs) -> SdStatus:
    sd = await cam.sd_card()
    return {"present": bool(sd.present), "remaining_mb": sd.remaining_mb, "total_mb": sd.total_mb}


async def op_version(cam: CameraAPI, args: OpArgs) -> str:
    return await cam.version()


async def op_range(cam: CameraAPI, args: OpArgs) -> float | None:
    return await cam.range()


async def op_network(cam: CameraAPI, args: OpArgs) -> dict[str, str | None]:
    return await cam.network()


async def op_set_network(cam: CameraAPI, args: OpArgs) -> None:
    values = args.get("values") or {}
    if not isinstance(values, Mapping) or not values:
        raise OpError("values must name the settings to write (address, gateway, ...)")
    if not _flag(args, "confirmed"):
        raise OpError("writing network settings changes the camera's address: confirm first (confirmed: true)")
    return await cam.set_network(**{k: v for k, v in values.items() if v not in (None, "")})


OPS: dict[str, OpHandler] = {
    "request": op_request,
    "raw": op_raw,
    "point": op_point,
    "rates": op_rates,
    "stop": op_stop,
    "center": op_center,
    "mode": op_mode,
    "ptz": op_ptz,
    "photo": op_photo,
    "record": op_record,
    "recording": op_recording,
    "sd": op_sd,
    "version": op_version,
    "range": op_range,
    "network": op_network,
    "set_network": op_set_network,
}
