"""Motion commands of the device CLI: `point`, `set_angles`, `rate` (split from device_cmds.py).

`point` returns once the attitude is there, on a model that reports its attitude. A model that
reports none (the C13) cannot confirm a position: `point` then sends the angles, waits the time the
slew needs from the model's ranges and rates, and says plainly that the position is not confirmed
(`"confirmed": false`, exit 0). `set_angles` only sends the angles (never confirmed)."""

from __future__ import annotations

import argparse
from collections.abc import Callable, Mapping
from typing import TYPE_CHECKING

from ..client.roles import readable
from ..errors import FieldValueError
from ..protocol import DeviceModel, Dialect, all_models, get_model
from .args import number
from .device_output import attitude_dict, ok

if TYPE_CHECKING:  # the client loads when a command runs, not for `topgimbal --help` (cli/main.py)
    from ..client import AsyncClient

Register = Callable[..., argparse.ArgumentParser]
SETTLE_S = 0.5  # added to the computed slew: the frame's trip and the gimbal's settling

# API argument -> the CLI's words for it (errors name what the user typed)
_POINT_OPTIONS = {
    "yaw_deg": "YAW",
    "pitch_deg": "PITCH",
    "roll_deg": "--roll",
    "speed_deg_s": "--speed",
    "yaw_speed_deg_s": "--speed",
    "pitch_speed_deg_s": "--speed",
    "tolerance_deg": "--tolerance",
    "timeout_s": "--wait",
}


def _as_typed(exc: FieldValueError) -> FieldValueError:
    """The same error naming the CLI argument (YAW, --speed) instead of the API's keyword."""
    option = _POINT_OPTIONS.get(exc.field)
    if option is None:
        return exc
    return FieldValueError(option, exc.value, exc.allowed)


def default_speed_deg_s(dialect: Dialect, model: DeviceModel) -> float:
    """The slew speed an angle command sends when none is given: its speed field's catalog
    default, capped by the model's rate limit (the model's limit when the command has none)."""
    spec = dialect.by_role("angle", model)
    if spec is not None:
        for f in spec.request_form("w").fields:
            if f.name.endswith("speed_deg_s") and isinstance(f.default, (int, float)) and f.default > 0:
                return min(float(f.default), model.max_rate_deg_s)
    return model.max_rate_deg_s


def slew_time_s(model: DeviceModel, targets: Mapping[str, float], speed_deg_s: float) -> float:
    """How long a slew to `targets` ({axis: deg}) takes at most from anywhere in the model's ranges
    (nothing says where the gimbal starts): the farthest end of each axis's range at `speed_deg_s`,
    plus the time to reach that speed at the model's acceleration, plus SETTLE_S."""
    ranges = {"yaw": model.yaw_range_deg, "pitch": model.pitch_range_deg, "roll": model.roll_range_deg}
    worst = 0.0
    for axis, target in targets.items():
        lo, hi = ranges[axis]
        worst = max(worst, abs(target - lo), abs(hi - target))
    accel = model.max_accel_deg_s2 or 0.0
    ramp = speed_deg_s / accel if accel > 0 else 0.0
    return worst / speed_deg_s + ramp + SETTLE_S


async def _send_angles(cam: AsyncClient, args: argparse.Namespace) -> dict[str, float]:
    targets = {"yaw": args.yaw, "pitch": args.pitch}
    if getattr(args, "roll", None) is not None:
        targets["roll"] = args.roll
    try:
        await cam.set_angles(args.yaw, args.pitch, targets.get("roll"), speed_deg_s=args.speed)
    except FieldValueError as exc:
        raise _as_typed(exc) from None
    return targets


def _unconfirmed(cam: AsyncClient, targets: Mapping[str, float], **extra: object) -> dict[str, object]:
    out: dict[str, object] = {f"{axis}_deg": v for axis, v in targets.items()}
    out.update(confirmed=False, **extra)
    out["note"] = (
        f"the {cam.model.name} reports no attitude: the angles were sent, the position is not confirmed"
        if "waited_s" in out
        else "angles sent; the position is not confirmed (point waits for it where the model reports attitude)"
    )
    return out


async def _point(cam: AsyncClient, args: argparse.Namespace) -> dict[str, object]:
    if readable(cam.dialect, cam.model, "attitude") is None:
        return await _point_blind(cam, args)
    try:
        att = await cam.point(
            args.yaw, args.pitch, tolerance_deg=args.tolerance, timeout_s=args.wait, speed_deg_s=args.speed
        )
    except FieldValueError as exc:
        raise _as_typed(exc) from None
    return {**attitude_dict(att), "confirmed": True}


async def _point_blind(cam: AsyncClient, args: argparse.Namespace) -> dict[str, object]:
    """`point` on a model without attitude: send, wait the slew time (or --wait), say unconfirmed."""
    speed = args.speed if args.speed else default_speed_deg_s(cam.dialect, cam.model)
    targets = await _send_angles(cam, args)
    wait_s = args.wait if args.wait is not None else slew_time_s(cam.model, targets, speed)
    import asyncio  # here, not at the top: `topgimbal --help` does not load asyncio (cli/main.py)

    await asyncio.sleep(wait_s)
    return _unconfirmed(cam, targets, waited_s=round(wait_s, 1))


async def _set_angles(cam: AsyncClient, args: argparse.Namespace) -> dict[str, object]:
    targets = await _send_angles(cam, args)
    return {**ok("set_angles"), **_unconfirmed(cam, targets)}


# The rate fields (API and wire names) -> the CLI's words and the argument holding what was typed:
# the wire value has the model's sign applied, and "-20 is not allowed" after typing 20 misleads.
_RATE_OPTIONS = {
    "yaw": ("YAW_RATE", "yaw_rate"),
    "pitch": ("PITCH_RATE", "pitch_rate"),
    "roll": ("--roll-rate", "roll_rate"),
}


async def _rate(cam: AsyncClient, args: argparse.Namespace) -> dict[str, object]:
    import asyncio  # here, not at the top: `topgimbal --help` does not load asyncio (cli/main.py)

    try:
        if args.duration:
            async with cam.rate_control(interval_s=0.1) as joy:
                joy.set(args.yaw_rate, args.pitch_rate, args.roll_rate)
                await asyncio.sleep(args.duration)
            return ok("rate", stopped=True)
        await cam.rates(args.yaw_rate, args.pitch_rate, args.roll_rate)
    except FieldValueError as exc:
        axis = exc.field.split("_", 1)[0]
        if axis not in _RATE_OPTIONS or "deg_s" not in exc.field:
            raise
        option, dest = _RATE_OPTIONS[axis]
        raise FieldValueError(option, getattr(args, dest), exc.allowed) from None
    return ok("rate")


RATE = number(what="a rate in deg/s")


def _point_ranges() -> tuple[str, str, str]:
    """Help text with the limits each model has, from the catalog and the model profiles."""
    yaw: dict[str, list[str]] = {}
    pitch: dict[str, list[str]] = {}
    speeds: dict[str, str] = {}
    for name in all_models():
        dialect, model = get_model(name)
        yaw.setdefault("{:g}..{:g}".format(*model.yaw_range_deg), []).append(name)
        pitch.setdefault("{:g}..{:g}".format(*model.pitch_range_deg), []).append(name)
        gay = dialect.command("GAY").request_form("w")
        speeds[dialect.name] = next(f.codec.allowed() for f in gay.fields if f.name == "speed_deg_s")

    def join(ranges: dict[str, list[str]]) -> str:
        return "; ".join(f"{', '.join(models)}: {r}" for r, models in ranges.items())

    speed = (
        "; ".join(f"{d}: {a}" for d, a in speeds.items())
        if len(set(speeds.values())) > 1
        else next(iter(speeds.values()))
    )
    return join(yaw), join(pitch), speed


def register(sub: argparse._SubParsersAction, command: Register, seconds: Callable[[str], float]) -> None:
    yaw_help, pitch_help, speed_help = _point_ranges()
    p = command(
        sub,
        "point",
        _point,
        "move to YAW PITCH (degrees) and return once reached; on a model that reports no attitude "
        "(C13): send, wait the slew time, report it unconfirmed",
    )
    p.add_argument("yaw", type=float, help=f"degrees, right-positive ({yaw_help})")
    p.add_argument("pitch", type=float, help=f"degrees, up-positive ({pitch_help})")
    p.add_argument("--tolerance", type=float, default=0.5, help="degrees (default 0.5)")
    p.add_argument("--speed", type=float, default=None, help=f"slew speed: {speed_help}")
    p.add_argument(
        "--wait",
        type=seconds,
        default=None,
        metavar="S",
        help="give up after S seconds (without attitude: wait S seconds instead of the computed slew time)",
    )

    p = command(sub, "set_angles", _set_angles, "send absolute angles YAW PITCH (degrees) without waiting")
    p.add_argument("yaw", type=float, help=f"degrees, right-positive ({yaw_help})")
    p.add_argument("pitch", type=float, help=f"degrees, up-positive ({pitch_help})")
    p.add_argument("--roll", type=float, default=None, help="degrees (models with a roll angle command)")
    p.add_argument("--speed", type=float, default=None, help=f"slew speed: {speed_help}")

    p = command(sub, "rate", _rate, "turn at constant rates in deg/s (stop with `stop`)")
    p.add_argument("yaw_rate", type=RATE, metavar="YAW_RATE", help="deg/s, right-positive")
    p.add_argument("pitch_rate", type=RATE, nargs="?", default=0.0, metavar="PITCH_RATE", help="deg/s, up-positive")
    p.add_argument("--roll-rate", dest="roll_rate", type=RATE, default=0.0)
    p.add_argument(
        "--duration",
        type=number(low=0, what="a duration"),
        default=0.0,
        metavar="S",
        help="keep the rates alive for S seconds, then stop (default 0: set them and return)",
    )
