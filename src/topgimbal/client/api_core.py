"""Typed methods, part 1: any catalog command, raw frames, attitude, identity.

Each method is one coroutine function taking the client core; `api_method` makes it a coroutine
method of `AsyncClient` and a blocking method of `Gimbal` (see methods.py)."""

from __future__ import annotations

import asyncio
import contextlib
from collections.abc import Mapping
from typing import Protocol

from ..errors import DecodeError, DeviceError, LinkLostError, RequestTimeoutError, TopGimbalError, UnsupportedError
from ..protocol import Frame, Message, decode_any, parse_frame
from ..protocol.frame import complete_frame
from ..timeouts import within
from . import checks, identity, model_check, roles
from .core import ClientCore
from .methods import api_method
from .signs import map_message
from .state import GimbalAttitude, StateCache, attitude_of


def fields_of(m: Message) -> dict[str, object]:
    """The fields of an answer, or DecodeError saying what it is (and, when another dialect reads
    it, which `--model` would fit)."""
    if m.fields is not None:
        return m.fields
    text = f"cannot read the device's answer {m.frame.text()}: {m.error}"
    other = decode_any(m.frame, prefer=m.dialect or None)
    if other.fields is not None and other.dialect and other.dialect != m.dialect:
        fits = identity.models_of_dialect(other.dialect, m.frame.ident)
        text += (
            f"; it reads as a {other.dialect} frame ({other.fields}): the device may be a "
            f"{' or '.join(fits) or other.dialect} model, so pass --model {fits[0] if fits else '...'}"
        )
    else:
        text += "; if the device is another model, pass --model (connect(model=...))"
    raise DecodeError(text, answer=m.frame)


async def send_values(core: ClientCore, ident: str, values: Mapping[str, object]) -> Message:
    """`request(core, ident, **values)` for values held in a mapping."""
    return await core.send_request(core.build_from(ident, values))


# -- attitude ------------------------------------------------------------------------------------


def _rate(rate_hz: float) -> float:
    if not checks.is_number(rate_hz) or not 0 < rate_hz <= 1000:
        from ..errors import FieldValueError

        raise FieldValueError("rate_hz", rate_hz, "a rate in Hz above 0 (the device streams at most 100 Hz)")
    return float(rate_hz)


# -- identity ------------------------------------------------------------------------------------


class CoreMethods(Protocol):
    @api_method
    async def request(
        core: ClientCore,
        ident: str,
        *,
        read: bool = False,
        timeout_s: float | None = None,
        retries: int | None = None,
        wait_reply: bool | None = None,
        dst: str | None = None,
        **values: object,
    ) -> Message:
        """Send one catalog command and return the device's answer (fields in API units).

        Everything is checked before anything is sent (argument types, model support, value ranges).
        Only idempotent frames are retried (queries, absolute set-points); toggles, relative steps and
        photos are sent once. Raises RequestTimeoutError, DeviceError (ERE, or an acknowledgement
        that does not carry the data sent), LinkLostError or TransportError."""
        checks.positive_seconds("timeout_s", timeout_s)
        checks.count("retries", retries)
        frame = core.build_from(ident, values, read=read, dst=dst)
        return await core.send_request(frame, timeout_s=timeout_s, retries=retries, wait_reply=wait_reply)

    @api_method
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
        wire = core.dialect.decode(frame).fields if frame.ident in core.model.echo_rules else None
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

    @api_method
    async def attitude_stream(core: ClientCore, rate_hz: float = 50) -> None:
        """Ask the device to stream its attitude until `stop_attitude_stream()` (SkyDroid: at
        `rate_hz`, 1..100; TOPOTEK: on, at the device's own rate)."""
        rate = _rate(rate_hz)
        spec = core.dialect.command(roles.require_role(core.dialect, core.model, "attitude_stream", "attitude stream"))
        roles.stream_values(spec, rate)  # the range check, before anything changes
        await core.streams.set_manual(rate)

    @api_method
    async def stop_attitude_stream(core: ClientCore) -> None:
        """Stop a stream started with `attitude_stream()` (streams that consumers hold stay on)."""
        await core.streams.set_manual(None)

    @api_method
    async def get_attitude(core: ClientCore, *, earth: bool = False) -> GimbalAttitude:
        """Query the attitude once (`earth=True`: the gyro's earth-frame reading, where there is one).
        While a stream runs, the query is answered by the first frame that comes after it."""
        role = "earth_attitude" if earth else "attitude"
        ident = roles.require_role(
            core.dialect, core.model, role, "earth-frame attitude" if earth else "attitude query"
        )
        m = await request(core, ident, read=True)
        fields_of(m)  # a DecodeError for an answer that cannot be read
        att = attitude_of(StateCache.values_of(m), role, m.frame.ident)
        if att is None:
            raise DecodeError(f"{m.frame.text()} carries no {role.replace('_', ' ')}", answer=m.frame)
        return att

    @api_method
    async def wait_attitude(
        core: ClientCore, *, newer_than: float = 0.0, timeout_s: float | None = None
    ) -> GimbalAttitude:
        """The next sample of a running attitude stream (arrived after `newer_than`, monotonic).
        Starts no stream; RequestTimeoutError when none comes."""
        checks.positive_seconds("timeout_s", timeout_s)
        return await core.streams.next_sample(
            newer_than=newer_than, timeout_s=core.timeout_s * 3 if timeout_s is None else float(timeout_s)
        )

    @api_method
    async def version(core: ClientCore) -> str:
        ident = roles.require_role(core.dialect, core.model, "version", "version query")
        return str(fields_of(await request(core, ident, read=True))["version"])

    @api_method
    async def identify(core: ClientCore, *, timeout_s: float | None = None) -> dict[str, str | None]:
        """Ask the device who it is: its version, model name and hardware version where the model has
        such queries (a model name that comes late, as a C12's may, is not waited for beyond the
        timeout). Returns `{"dialect", "model", "version", "model_name", "hardware_version",
        "model_check"}` with None for parts it does not answer; raises when it answers nothing."""
        checks.positive_seconds("timeout_s", timeout_s)
        out: dict[str, str | None] = {"dialect": core.dialect.name, "model": core.model.name}
        errors: list[TopGimbalError] = []
        for role in ("version", "model_name", "hardware_version"):
            out[role] = None
            spec = roles.readable(core.dialect, core.model, role)
            if spec is None:
                continue
            try:
                m = await request(core, spec.ident, read=True, timeout_s=timeout_s)
                out[role] = roles.answer_text(spec, fields_of(m))
            except (RequestTimeoutError, DeviceError, UnsupportedError) as exc:
                errors.append(exc)
        if errors and all(out[r] is None for r in ("version", "model_name", "hardware_version")):
            raise errors[0]
        if core.identity.verdict.status == identity.PENDING:
            # The device has answered: its model check concludes in moments. Without this wait a
            # loaded machine printed `model_check: pending` for a healthy camera (its check ran on
            # behind the command's own queries).
            with contextlib.suppress(asyncio.TimeoutError):
                await within(core.identity.done.wait(), timeout_s)
        verdict = core.identity.verdict
        out["model_check"] = verdict.status if verdict.status != "mismatch" else verdict.message
        if core.feeds.active:  # what the host feeds the camera (position, time, attitude)
            out["feeds"] = core.feeds.summary()
        return out

    @api_method
    async def detect_model(core: ClientCore, *, timeout_s: float = 0.5) -> str | None:
        """Which model the device is, from its identity answers in every dialect (version, model name)
        compared with the profiles' identity strings. Returns a model name (when the answers match no
        profile, the dialect that answered gives its usual model), or None if nothing answered."""
        checks.positive_seconds("timeout_s", timeout_s, allow_none=False)
        try:
            return await model_check.detect(core, float(timeout_s), default="C12", checker=core.identity)
        except LinkLostError:
            return None  # nothing answered any probe for the link timeout

    @api_method
    async def vehicle_attitude(core: ClientCore, yaw_deg: float, pitch_deg: float, roll_deg: float) -> None:
        """Give the gimbal the vehicle's attitude (degrees). Where the model's profile asks for it
        continuously (C11: FAI at 10 Hz after FAE on), the client keeps sending the latest values in
        the background; otherwise it is sent once and acknowledged."""
        spec = roles.require(core.dialect, core.model, "vehicle_attitude", "vehicle attitude input")
        names = {f.name for f in spec.forms_for("w", "request")[0].fields}
        values = {
            k: v for k, v in (("yaw_deg", yaw_deg), ("pitch_deg", pitch_deg), ("roll_deg", roll_deg)) if k in names
        }
        await core.feeds.vehicle_attitude(values)


# The methods' own calls to each other (and the other api_* modules'): the plain functions.
request = CoreMethods.request.fn
get_attitude = CoreMethods.get_attitude.fn
