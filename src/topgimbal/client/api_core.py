"""Typed methods, part 1: any catalog command, raw frames, attitude, identity.

Each method is one coroutine function taking the client core; `api_method` makes it a coroutine
method of `AsyncClient` and a blocking method of `Gimbal` (see methods.py)."""

from __future__ import annotations

import time
from typing import Any

from ..errors import DeviceError, LinkLostError, RequestTimeoutError, TopGimbalError, UnsupportedError
from ..protocol import DIALECT_NAMES, Frame, Message, get_dialect, parse_frame
from ..protocol.frame import complete_frame
from . import checks, roles
from .core import ClientCore
from .methods import api_method
from .signs import map_message
from .state import Attitude


def fields_of(m: Message) -> dict[str, Any]:
    if m.fields is None:
        raise DeviceError(f"cannot read the device's answer {m.frame.text()}: {m.error}")
    return m.fields


async def request(
    core: ClientCore,
    ident: str,
    *,
    read: bool = False,
    timeout_s: float | None = None,
    retries: int | None = None,
    wait_reply: bool | None = None,
    dst: str | None = None,
    **values: Any,
) -> Message:
    """Send one catalog command and return the device's answer (fields in API units).

    Everything is checked before anything is sent (argument types, model support, value ranges).
    Only idempotent frames are retried (queries, absolute set-points); toggles, relative steps and
    photos are sent once. Raises RequestTimeoutError, DeviceError (ERE, or an acknowledgement
    that does not carry the data sent), LinkLostError or TransportError."""
    checks.positive_seconds("timeout_s", timeout_s)
    checks.count("retries", retries)
    frame = core.build(ident, read=read, dst=dst, **values)
    spec = core.dialect.command(frame.ident)
    if wait_reply is None:
        wait_reply = read or (spec.echo and (core.echo_motion or not spec.motion))
    exclusive = not spec.is_idempotent(frame)  # the engine sends it once (and waits as long in all)
    n = core.retries if retries is None else retries
    wire = core.dialect.decode(frame).fields if frame.ident in roles.ACK_REPORTS else None
    reply = await core._request(
        frame,
        timeout_s=core.timeout_s if timeout_s is None else float(timeout_s),
        retries=n,
        expect_reply=wait_reply,
        exclusive=exclusive,
        fields=wire,
    )
    if reply is None:
        return Message(frame, spec, None, None, "sent without waiting for a reply")
    return reply  # already in the API convention (mapped on arrival)


async def send_raw(
    core: ClientCore, frame: Frame | str | bytes, *, wait_reply: bool = True, timeout_s: float | None = None
) -> Message | None:
    """Send a frame as given (no validation, sign mapping or retries) and return the reply as on
    the wire. Text without its checksum is completed, as the console does."""
    checks.positive_seconds("timeout_s", timeout_s)
    if not isinstance(frame, Frame):
        frame = parse_frame(complete_frame(frame))
    spec = core.dialect.commands.get(frame.ident)
    exclusive = spec is not None and not spec.is_idempotent(frame)
    wire = core.dialect.decode(frame).fields if frame.ident in roles.ACK_REPORTS else None
    reply = await core._request(
        frame,
        timeout_s=core.timeout_s if timeout_s is None else float(timeout_s),
        retries=0,
        expect_reply=wait_reply,
        exclusive=exclusive,
        fields=wire,
    )
    # Replies are held in the API convention; the sign map is its own inverse.
    return None if reply is None else map_message(reply, core.signs)


# -- attitude ------------------------------------------------------------------------------------


def _rate(rate_hz: float) -> float:
    if not checks.is_number(rate_hz) or not 0 < rate_hz <= 1000:
        from ..errors import FieldValueError

        raise FieldValueError("rate_hz", rate_hz, "a rate in Hz above 0 (the device streams at most 100 Hz)")
    return float(rate_hz)


async def attitude_stream(core: ClientCore, rate_hz: float = 50) -> None:
    """Ask the device to stream its attitude until `stop_attitude_stream()` (SkyDroid: at
    `rate_hz`, 1..100; TOPOTEK: on, at the device's own rate)."""
    rate = _rate(rate_hz)
    spec = core.dialect.command(roles.require_role(core.dialect, core.model, "attitude_stream", "attitude stream"))
    roles.stream_values(spec, rate)  # the range check, before anything changes
    await core.streams.set_manual(rate)


async def stop_attitude_stream(core: ClientCore) -> None:
    """Stop a stream started with `attitude_stream()` (streams that consumers hold stay on)."""
    await core.streams.set_manual(None)


async def get_attitude(core: ClientCore, *, earth: bool = False) -> Attitude:
    """Query the attitude once (`earth=True`: the gyro's earth-frame reading, where there is one).
    While a stream runs, the query is answered by the first frame that comes after it."""
    role = "attitude_earth" if earth else "attitude"
    ident = roles.require_role(core.dialect, core.model, role, "earth-frame attitude" if earth else "attitude query")
    m = await request(core, ident, read=True)
    f = fields_of(m)
    return Attitude(f["yaw_deg"], f["pitch_deg"], f["roll_deg"], time.monotonic(), time.time(), m.frame.ident)


async def wait_attitude(core: ClientCore, *, newer_than: float = 0.0, timeout_s: float | None = None) -> Attitude:
    """The next sample of a running attitude stream (arrived after `newer_than`, monotonic).
    Starts no stream; RequestTimeoutError when none comes."""
    checks.positive_seconds("timeout_s", timeout_s)
    return await core.streams.next_sample(
        newer_than=newer_than, timeout_s=core.timeout_s * 3 if timeout_s is None else float(timeout_s)
    )


# -- identity ------------------------------------------------------------------------------------


async def version(core: ClientCore) -> str:
    ident = roles.require_role(core.dialect, core.model, "version", "version query")
    return str(fields_of(await request(core, ident, read=True))["version"])


async def identify(core: ClientCore, *, timeout_s: float | None = None) -> dict[str, Any]:
    """Ask the device who it is (its version, and its model name where it has one). Returns
    `{"dialect", "model", "version", "model_name"}` with None for parts it does not answer;
    raises when it answers nothing at all (a silent device says so)."""
    checks.positive_seconds("timeout_s", timeout_s)
    out: dict[str, Any] = {"dialect": core.dialect.name, "model": core.model.name, "version": None, "model_name": None}
    errors: list[TopGimbalError] = []
    for role, key, field in (("version", "version", "version"), ("model_name", "model_name", "model")):
        ident = roles.role_ident(core.dialect, core.model, role)
        if ident is None:
            continue
        try:
            out[key] = fields_of(await request(core, ident, read=True, timeout_s=timeout_s))[field]
        except (RequestTimeoutError, DeviceError, UnsupportedError) as exc:
            errors.append(exc)
    if errors and out["version"] is None and out["model_name"] is None:
        raise errors[0]
    if out["model_name"] is not None:
        core.state.set("model_name", out["model_name"])
    return out


async def detect_model(core: ClientCore, *, timeout_s: float = 0.5) -> str | None:
    """Which dialect the device speaks, by asking what only one dialect answers (a model-name
    query, then a version query). Returns a model name, or None if nothing answered."""
    checks.positive_seconds("timeout_s", timeout_s, allow_none=False)
    dialects = [get_dialect(name) for name in DIALECT_NAMES]
    for role in ("model_name", "version"):
        for d in dialects:
            for model in d.models.values():
                ident = roles.role_ident(d, model, role)
                if ident is None:
                    continue
                src = core.host_address if core.host_address in d.host_addresses else d.host_addresses[0]
                probe = d.encode(ident, read=True, src=src)
                try:
                    await core._request(probe, timeout_s=float(timeout_s), retries=1)
                except (RequestTimeoutError, DeviceError):
                    break  # this dialect's probe got no answer: try the next
                except LinkLostError:
                    return None  # nothing answered any probe for the link timeout
                if d is core.dialect:
                    return core.model.name
                return roles.DETECTED_MODEL.get(ident, model.name)
    return None


class CoreMethods:
    request = api_method(request)
    send_raw = api_method(send_raw)
    attitude_stream = api_method(attitude_stream)
    stop_attitude_stream = api_method(stop_attitude_stream)
    get_attitude = api_method(get_attitude)
    wait_attitude = api_method(wait_attitude)
    version = api_method(version)
    identify = api_method(identify)
    detect_model = api_method(detect_model)
