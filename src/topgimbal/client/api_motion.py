"""Typed methods, part 2: moving the gimbal (degrees and deg/s in the API sign convention)."""

from __future__ import annotations

import asyncio
import contextlib
import time
from typing import Any

from ..errors import FieldValueError, RequestTimeoutError, UnsupportedError
from . import checks
from .api_core import get_attitude, request
from .core import ClientCore
from .methods import api_method
from .state import Attitude

_REQUEST_OPTIONS = ("wait_reply", "timeout_s", "retries")


def _check_axis(core: ClientCore, axis: str, value: float | None) -> None:
    if value is None:
        return
    lo, hi = getattr(core.model, f"{axis}_range_deg")
    if not checks.is_number(value) or not lo <= value <= hi:
        raise FieldValueError(f"{axis}_deg", value, f"{lo:g}..{hi:g} degrees on the {core.model.name}")


def _options(kw: dict[str, Any]) -> dict[str, Any]:
    unknown = sorted(set(kw) - set(_REQUEST_OPTIONS))
    if unknown:
        raise FieldValueError(unknown[0], kw[unknown[0]], f"one of the request options {', '.join(_REQUEST_OPTIONS)}")
    return kw


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
    goes out."""
    if frame not in ("body", "earth"):
        raise FieldValueError("frame", frame, "'body' or 'earth'")
    prefix = "GI" if frame == "earth" else "GA"
    if frame == "earth" and not core.dialect.supports(core.model, "GIY"):
        raise UnsupportedError(f"the {core.model.name} has no earth-frame angle commands")
    for axis, v in (("yaw", yaw_deg), ("pitch", pitch_deg), ("roll", roll_deg)):
        _check_axis(core, axis, v)
    sp: dict[str, Any] = {} if speed_deg_s is None else {"speed_deg_s": speed_deg_s}
    frames: list[tuple[str, dict[str, Any]]] = []
    if yaw_deg is not None and pitch_deg is not None and core.combined_motion:
        both: dict[str, Any] = {"yaw_deg": yaw_deg, "pitch_deg": pitch_deg}
        if speed_deg_s is not None:
            both.update(yaw_speed_deg_s=speed_deg_s, pitch_speed_deg_s=speed_deg_s)
        frames.append((prefix + "M", both))
    else:
        if yaw_deg is not None:
            frames.append((prefix + "Y", {"yaw_deg": yaw_deg, **sp}))
        if pitch_deg is not None:
            frames.append((prefix + "P", {"pitch_deg": pitch_deg, **sp}))
    if roll_deg is not None:
        frames.append((prefix + "R", {"roll_deg": roll_deg, **sp}))
    for ident, values in frames:
        core.build(ident, **values)  # validate all before sending any
    for ident, values in frames:
        await request(core, ident, **values)


async def rates(
    core: ClientCore, yaw_deg_s: float = 0, pitch_deg_s: float = 0, roll_deg_s: float = 0, **kw: Any
) -> None:
    """Turn at constant rates (deg/s, API convention) until told otherwise. `kw`: wait_reply,
    timeout_s, retries (as for request)."""
    _options(kw)
    frames: list[tuple[str, dict[str, Any]]] = []
    if roll_deg_s and core.dialect.supports(core.model, "YPR"):
        frames.append(
            ("YPR", {"yaw_rate_deg_s": yaw_deg_s, "pitch_rate_deg_s": pitch_deg_s, "roll_rate_deg_s": roll_deg_s})
        )
    elif core.combined_motion:
        frames.append(("GSM", {"yaw_rate_deg_s": yaw_deg_s, "pitch_rate_deg_s": pitch_deg_s}))
        if roll_deg_s:
            frames.append(("GSR", {"roll_rate_deg_s": roll_deg_s}))
    else:
        frames += [("GSY", {"yaw_rate_deg_s": yaw_deg_s}), ("GSP", {"pitch_rate_deg_s": pitch_deg_s})]
        if roll_deg_s:
            frames.append(("GSR", {"roll_rate_deg_s": roll_deg_s}))
    for ident, values in frames:
        core.build(ident, **values)
    for ident, values in frames:
        await request(core, ident, **values, **kw)


async def stop(core: ClientCore) -> None:
    """Stop all motion the way real devices need: zero rates sent several times (a lost stop
    leaves the gimbal turning), then PTZ stop, answered."""
    zero = core.build("GSM", yaw_rate_deg_s=0, pitch_rate_deg_s=0)
    for _ in range(max(0, core.stop_repeats - 1)):
        await core._request(zero, timeout_s=core.timeout_s, retries=0, expect_reply=False)
    await rates(core, 0, 0, 0)
    await request(core, "PTZ", action="stop")


async def center(core: ClientCore) -> None:
    await request(core, "PTZ", action="center")


async def set_mode(core: ClientCore, mode: str) -> None:
    """`follow` (the camera follows the vehicle's heading) or `lock` (holds its heading)."""
    if mode not in ("follow", "lock"):
        raise FieldValueError("mode", mode, "'follow' or 'lock'")
    await request(core, "PTZ", action=mode)
    core.state.set("mode", mode)


async def point(
    core: ClientCore,
    yaw_deg: float,
    pitch_deg: float,
    *,
    tolerance_deg: float = 0.5,
    timeout_s: float | None = None,
    speed_deg_s: float | None = None,
    poll_s: float = 0.05,
) -> Attitude:
    """Move to (yaw, pitch) and return once the attitude is within `tolerance_deg` on both axes.
    Uses the attitude stream when one runs, and polls when no sample comes. RequestTimeoutError
    (with the last attitude seen) otherwise; the default timeout allows for the slew."""
    _check_axis(core, "yaw", yaw_deg)
    _check_axis(core, "pitch", pitch_deg)
    if not checks.is_number(tolerance_deg) or tolerance_deg <= 0:
        raise FieldValueError("tolerance_deg", tolerance_deg, "degrees above 0")
    checks.positive_seconds("timeout_s", timeout_s)
    checks.positive_seconds("poll_s", poll_s, allow_none=False)
    now_att = core.state.attitude
    if now_att is None or time.monotonic() - now_att.t > 1.0:
        with contextlib.suppress(RequestTimeoutError):
            now_att = await get_attitude(core)
    if timeout_s is None:
        dist = 180.0 if now_att is None else max(abs(yaw_deg - now_att.yaw_deg), abs(pitch_deg - now_att.pitch_deg))
        speed = speed_deg_s or min(9.9, core.model.max_rate_deg_s)
        timeout_s = dist / max(speed, 0.5) * 1.5 + 3.0
    loop = asyncio.get_running_loop()
    deadline = loop.time() + timeout_s
    await set_angles(core, yaw_deg, pitch_deg, speed_deg_s=speed_deg_s)
    last: Attitude | None = None
    while (remaining := deadline - loop.time()) > 0:
        sample: Attitude | None = None
        rate = core.streams.device_rate
        if rate is not None:
            wait = min(remaining, max(0.25, 3.0 / rate))
            with contextlib.suppress(RequestTimeoutError):
                sample = await core.streams.next_sample(newer_than=last.t if last else 0.0, timeout_s=wait)
        polled = sample is None
        if polled:
            try:
                sample = await get_attitude(core)
            except RequestTimeoutError:
                continue
        assert sample is not None
        last = sample
        if abs(sample.yaw_deg - yaw_deg) <= tolerance_deg and abs(sample.pitch_deg - pitch_deg) <= tolerance_deg:
            return sample
        if polled:
            await asyncio.sleep(min(poll_s, max(0.0, deadline - loop.time())))
    if last is None:
        where = "; no attitude came from the device meanwhile"
    else:
        age = time.monotonic() - last.t
        where = (
            f"; last attitude seen: yaw {last.yaw_deg:.2f}, pitch {last.pitch_deg:.2f}, roll {last.roll_deg:.2f} "
            f"({last.source}, {age:.1f} s ago)"
        )
    raise RequestTimeoutError(f"did not reach yaw {yaw_deg:g}, pitch {pitch_deg:g} within {timeout_s:.1f} s{where}")


class MotionMethods:
    set_angles = api_method(set_angles)
    rates = api_method(rates)
    stop = api_method(stop)
    center = api_method(center)
    set_mode = api_method(set_mode)
    point = api_method(point)
