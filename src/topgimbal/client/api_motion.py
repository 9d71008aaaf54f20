"""Typed methods, part 2: moving the gimbal (degrees and deg/s in the API sign convention).

Which command moves which axis is catalog metadata (role `rate` / `angle` / `earth_angle` and the
fields' axes); commands the model's firmware ignores (its profile's `ignored`) are never used, so
on a C11 rates go out as GSY + GSP and `point()` closes the loop over them."""

from __future__ import annotations

import asyncio
import contextlib
import logging
from typing import Protocol

from ..clock import monotonic
from ..errors import FieldValueError, RequestTimeoutError, TopGimbalError, UnsupportedError
from ..protocol import Frame
from . import checks, roles
from .api_core import get_attitude, request
from .core import ClientCore
from .methods import api_method
from .pointing import AxisLimits, RateLoop, stalled, within
from .state import GimbalAttitude, attitude_of
from .streams import AttitudeStream

log = logging.getLogger("topgimbal.client")

_REQUEST_OPTIONS = ("wait_reply", "timeout_s", "retries")
STALL_S = 1.0  # an angle command after which nothing at all has moved for this long was ignored
STALE_S = 0.2  # closed loop: no fresh attitude for this long stops the gimbal until one comes


def _check_axis(core: ClientCore, axis: str, value: float | None) -> None:
    if value is None:
        return
    lo, hi = getattr(core.model, f"{axis}_range_deg")
    if not checks.is_number(value) or not lo <= value <= hi:
        raise FieldValueError(f"{axis}_deg", value, f"{lo:g}..{hi:g} degrees on the {core.model.name}")


def _frames(core: ClientCore, role: str, wanted: dict[str, float], speed_deg_s: float | None = None) -> list[Frame]:
    """The frames that set `wanted` with commands of `role`, each built (and so range-checked by the
    builder) once: all of them before the caller sends any, and what it sends are these frames."""
    plan = roles.motion_plan(
        core.dialect, core.model, role, wanted, combined=core.behaviour.combined, speed_deg_s=speed_deg_s
    )
    return [core.build_from(cmd.spec.ident, cmd.values) for cmd in plan]


async def _send_angles(core: ClientCore, frames: list[Frame]) -> None:
    for frame in frames:
        await core.send_request(frame)


def _zero_rates(core: ClientCore) -> list[Frame]:
    axes = [a for a in ("yaw", "pitch") if roles.can_move(core.dialect, core.model, "rate", [a])]
    return _frames(core, "rate", {a: 0.0 for a in axes}) if axes else []


async def _sample(core: ClientCore, after: float, wait_s: float) -> GimbalAttitude | None:
    """The next attitude sample newer than `after`: from a running stream, else by asking (None
    when neither comes within about `wait_s`)."""
    rate = core.streams.device_rate
    if rate is not None:
        with contextlib.suppress(RequestTimeoutError):
            return await core.streams.next_sample(newer_than=after, timeout_s=min(wait_s, max(0.25, 3.0 / rate)))
    spec = roles.require(core.dialect, core.model, "attitude", "attitude query")
    try:
        m = await request(core, spec.ident, read=True, timeout_s=min(core.timeout_s, max(wait_s, 0.05)))
    except RequestTimeoutError:
        return None
    return attitude_of(core.state.values_of(m), "attitude", m.ident)


def _where(last: GimbalAttitude | None) -> str:
    if last is None:
        return "; no attitude came from the device meanwhile"
    return (
        f"; last attitude seen: yaw {last.yaw_deg:.2f}, pitch {last.pitch_deg:.2f}, roll {last.roll_deg:.2f} "
        f"({last.source}, {monotonic() - last.t:.1f} s ago)"
    )


def _rate_cap(core: ClientCore) -> float:
    return min(roles.rate_limits(core.dialect, core.model, a)[0] for a in ("yaw", "pitch"))


async def _closed_loop(
    core: ClientCore, targets: dict[str, float], tolerance_deg: float, deadline: float, last: GimbalAttitude | None
) -> GimbalAttitude:
    """Drive each axis by its rate command until the attitude is within the tolerance."""
    limits = {
        axis: AxisLimits(*roles.rate_limits(core.dialect, core.model, axis), core.model.max_accel_deg_s2)
        for axis in targets
    }
    control = RateLoop(targets, limits, tolerance_deg * 0.7)  # stop inside, to settle inside
    stream: AttitudeStream | None = None
    if roles.command(core.dialect, core.model, "attitude_stream") is not None:
        stream = AttitudeStream(core.streams, 50.0, abandon_after_s=3600.0)  # closed below
        with contextlib.suppress(TopGimbalError):
            await stream.start()
    moving = False
    try:
        while (remaining := deadline - monotonic()) > 0:
            sample = await _sample(core, last.t if last else 0.0, min(remaining, STALE_S))
            if sample is None:
                if moving:  # no feedback: never keep turning blind
                    await _halt(core)
                    moving = False
                continue
            last = sample
            rates = control.step(sample, monotonic())
            if rates is None:
                if not moving:
                    return sample  # inside the tolerance on a sample taken after the stop
                await _halt(core)
                moving = False
                continue
            if rates:
                moving = True
                for frame in _frames(core, "rate", rates):
                    core.send_nowait(frame)
        raise RequestTimeoutError(
            f"did not reach yaw {targets['yaw']:g}, pitch {targets['pitch']:g} by rate control in time{_where(last)}"
        )
    finally:
        if moving:
            with contextlib.suppress(TopGimbalError):
                await _halt(core)
        if stream is not None:
            await stream.aclose()


def _ignore_angles(core: ClientCore, waited_s: float) -> None:
    """Point by rate commands for the rest of this connection: the firmware ignores angles."""
    core.angles_ignored = True
    log.warning(
        "%s: nothing moved %.1f s after an angle command: pointing by rate commands from now on", core.url, waited_s
    )


async def _halt(core: ClientCore) -> None:
    """Zero rates, `stop_repeats` times (fire and forget: the attitude confirms)."""
    zero = _zero_rates(core)
    for _ in range(core.stop_repeats):
        for frame in zero:
            core.send_nowait(frame)


class MotionMethods(Protocol):
    @api_method
    async def set_angles(
        core: ClientCore,
        yaw_deg: float | None = None,
        pitch_deg: float | None = None,
        roll_deg: float | None = None,
        *,
        speed_deg_s: float | None = None,
        frame: str = "body",
    ) -> None:
        """Move to absolute angles (degrees, API convention). `frame="earth"` uses the gyro's
        earth-frame commands where the model has them. Every value is checked before the first frame
        goes out. UnsupportedError where the firmware ignores angle commands (use `point()`)."""
        if frame not in ("body", "earth"):
            raise FieldValueError("frame", frame, "'body' or 'earth'")
        wanted: dict[str, float] = {}
        for axis, v in (("yaw", yaw_deg), ("pitch", pitch_deg), ("roll", roll_deg)):
            _check_axis(core, axis, v)
            if v is not None:
                wanted[axis] = v
        await _send_angles(core, _frames(core, "earth_angle" if frame == "earth" else "angle", wanted, speed_deg_s))

    @api_method
    async def rates(
        core: ClientCore,
        yaw_deg_s: float = 0,
        pitch_deg_s: float = 0,
        roll_deg_s: float = 0,
        *,
        wait_reply: bool | None = None,
        timeout_s: float | None = None,
        retries: int | None = None,
    ) -> None:
        """Turn at constant rates (deg/s, API convention) until told otherwise (as for `request`:
        wait_reply, timeout_s, retries)."""
        wanted = {"yaw": yaw_deg_s, "pitch": pitch_deg_s}
        if roll_deg_s:
            wanted["roll"] = roll_deg_s
        checks.positive_seconds("timeout_s", timeout_s)
        checks.count("retries", retries)
        for frame in _frames(core, "rate", wanted):
            await core.send_request(frame, wait_reply=wait_reply, timeout_s=timeout_s, retries=retries)

    @api_method
    async def stop(core: ClientCore) -> None:
        """Stop all motion the way the model needs: zero rates and the stop code, each sent the
        profile's `stop_repeats` times (a single stop may be missed and the gimbal coast on: C13), the
        last ones acknowledged where the model acknowledges motion commands."""
        ptz = roles.command(core.dialect, core.model, "gimbal_control")
        halt = _zero_rates(core)
        if ptz is not None:
            halt.append(core.build(ptz.ident, action="stop"))
        for _ in range(core.stop_repeats - 1):
            for frame in halt:
                core.send_nowait(frame)
        for frame in halt:
            await core.send_request(frame)

    @api_method
    async def center(core: ClientCore) -> None:
        ptz = roles.require(core.dialect, core.model, "gimbal_control", "gimbal control codes")
        await request(core, ptz.ident, action="center")

    @api_method
    async def set_mode(core: ClientCore, mode: str) -> None:
        """`follow` (the camera follows the vehicle's heading) or `lock` (holds its heading)."""
        if mode not in ("follow", "lock"):
            raise FieldValueError("mode", mode, "'follow' or 'lock'")
        ptz = roles.require(core.dialect, core.model, "gimbal_control", "gimbal control codes")
        await request(core, ptz.ident, action=mode)
        core.state.set("mode", mode)

    @api_method
    async def point(
        core: ClientCore,
        yaw_deg: float,
        pitch_deg: float,
        *,
        tolerance_deg: float = 0.5,
        timeout_s: float | None = None,
        speed_deg_s: float | None = None,
        poll_s: float = 0.05,
    ) -> GimbalAttitude:
        """Move to (yaw, pitch) and return once the attitude is within `tolerance_deg` on both axes.

        With angle commands where the model obeys them; by closing the loop over rate commands fed by
        the attitude where its firmware ignores them (C11), or when nothing moves after an angle
        command (the client then keeps doing so for this connection). RequestTimeoutError (with the
        last attitude seen) otherwise; the default timeout allows for the slew."""
        _check_axis(core, "yaw", yaw_deg)
        _check_axis(core, "pitch", pitch_deg)
        if not checks.is_number(tolerance_deg) or tolerance_deg <= 0:
            raise FieldValueError("tolerance_deg", tolerance_deg, "degrees above 0")
        checks.positive_seconds("timeout_s", timeout_s)
        checks.positive_seconds("poll_s", poll_s, allow_none=False)
        if roles.readable(core.dialect, core.model, "attitude") is None:
            raise UnsupportedError(
                f"the {core.model.name} reports no attitude, so point() cannot tell when it is there; "
                "use set_angles() (sent, not confirmed)"
            )
        targets = {"yaw": float(yaw_deg), "pitch": float(pitch_deg)}
        closed = core.angles_ignored or not roles.can_move(core.dialect, core.model, "angle", list(targets))
        now_att = core.state.attitude
        if now_att is None or monotonic() - now_att.t > 1.0:
            with contextlib.suppress(RequestTimeoutError):
                now_att = await get_attitude(core)
        dist = 180.0 if now_att is None else max(abs(yaw_deg - now_att.yaw_deg), abs(pitch_deg - now_att.pitch_deg))
        speed = _rate_cap(core) if closed else (speed_deg_s or min(9.9, core.model.max_rate_deg_s))
        if timeout_s is None:
            timeout_s = dist / max(speed, 0.5) * 1.5 + 3.0
        deadline = monotonic() + timeout_s
        last: GimbalAttitude | None = now_att
        if not closed:  # the axes were checked above: build and send, no second check
            await _send_angles(core, _frames(core, "angle", targets, speed_deg_s))
            stall_s = max(STALL_S, 0.6 / speed_deg_s) if speed_deg_s else STALL_S
            start, started = now_att, monotonic()
            while (remaining := deadline - monotonic()) > 0:
                sample = await _sample(core, last.t if last else 0.0, remaining)
                if sample is None:
                    continue
                last = sample
                if within(targets, sample, tolerance_deg):
                    return sample
                if (
                    start is not None
                    and monotonic() - started >= stall_s
                    and stalled(start, sample, targets, tolerance_deg)
                ):
                    _ignore_angles(core, monotonic() - started)
                    deadline = max(deadline, monotonic() + dist / _rate_cap(core) * 1.5 + 3.0)
                    break
                if core.streams.device_rate is None:
                    await asyncio.sleep(min(poll_s, max(0.0, deadline - monotonic())))
            else:
                raise RequestTimeoutError(
                    f"did not reach yaw {yaw_deg:g}, pitch {pitch_deg:g} within {timeout_s:.1f} s{_where(last)}"
                )
        return await _closed_loop(core, targets, tolerance_deg, deadline, last)


# The methods' own calls to each other (and the other api_* modules'): the plain functions.
set_angles = MotionMethods.set_angles.fn
