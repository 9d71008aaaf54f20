"""Device commands: talk to a camera (or the simulator) at `--url` as `--model`.

Every command takes `--json` and `--timeout`; errors end as one line on stderr with exit code 1,
2 for input refused before sending (main.py).

The model: with `--model NAME` a command first waits (at most MODEL_CHECK_WAIT_S) for the model
check (client/model_check.py); when the device identifies itself as another model, nothing is sent
and the command exits 2 naming the model it found. `--model auto` (or no --model) asks the device
what it is and uses that. A contradiction heard only after the command ran makes it fail (exit 1)
without printing the answer, which was read through the wrong model's signs. Motion commands: device_motion.py. Stable forms scripts rely on: `attitude --json` (one object with yaw_deg, pitch_deg,
roll_deg), `point YAW PITCH`, `photo`, `record start|stop|status`."""

from __future__ import annotations

import argparse
import contextlib
import math
import sys
from collections.abc import Awaitable, Callable, Mapping
from typing import TYPE_CHECKING

from ..client.jsonable import dumps
from ..client.roles import focus_actions, role_ident
from ..client.state import SdCard
from ..clock import monotonic
from ..errors import (
    FieldValueError,
    InputError,
    RequestTimeoutError,
    TopGimbalError,
)
from ..protocol import DIALECT_NAMES, get_dialect
from ..protocol.fields import FieldValue
from . import device_motion, device_session, locate_cmd
from .args import COUNT, HZ, add_json_argument
from .device_output import attitude_dict, ok, show
from .model_check import AUTO_MODEL, detect, model_check_records_left_out, refuse_wrong_model, verdict_of, with_hint

if TYPE_CHECKING:  # the client loads when a command runs, not for `topgimbal --help` (cli/main.py)
    from ..client import AsyncClient

# A command's result is what `show` prints (an int is the exit status instead).
Runner = Callable[["AsyncClient", argparse.Namespace], Awaitable[object]]


# -- plumbing ------------------------------------------------------------------------------------


def _seconds(text: str) -> float:
    """argparse type: a number of seconds above zero."""
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text!r} is not a number of seconds") from None
    if not math.isfinite(value) or value <= 0:
        raise argparse.ArgumentTypeError(f"{text} s: give a time above 0, e.g. 0.5")
    return value


def _retries(text: str) -> int:
    try:
        value = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text!r} is not a whole number") from None
    if not 0 <= value <= 100:
        raise argparse.ArgumentTypeError(f"{value}: give 0..100 retries")
    return value


def _options(p: argparse.ArgumentParser) -> argparse.ArgumentParser:
    add_json_argument(p)
    p.add_argument(
        "--timeout", type=_seconds, default=1.0, metavar="S", help="reply timeout per request (default 1.0 s)"
    )
    p.add_argument("--retries", type=_retries, default=2, help="retries for idempotent requests (default 2)")
    p.add_argument("--log", metavar="FILE", help="append the traffic to a JSONL log")
    return p


def _command(sub: argparse._SubParsersAction, name: str, runner: Runner, help: str) -> argparse.ArgumentParser:
    p = _options(sub.add_parser(name, help=help, description=help))
    p.set_defaults(func=lambda args: _run(args, runner))
    return p


def _run(args: argparse.Namespace, runner: Runner) -> int:
    import asyncio

    from ..client import connect

    if not args.url:
        raise InputError("no device URL: pass --url URL (before the command) or set TOPGIMBAL_URL")

    async def main() -> object:
        model = args.model
        explicit = model is not None and model != AUTO_MODEL
        if not explicit:
            model = await detect(args)
        async with connect(
            args.url, model=model, timeout_s=args.timeout, retries=args.retries, log_path=args.log
        ) as cam:
            diagnostic = runner in DIAGNOSTICS  # says what the device is: runs, and shows the check
            if explicit and not diagnostic:
                await refuse_wrong_model(cam)
            try:
                result = await runner(cam, args)
            except TopGimbalError as exc:
                verdict = await verdict_of(cam)
                if verdict is not None and verdict.message not in str(exc):
                    raise with_hint(exc, verdict.message, cam.model.name) from None
                raise
            verdict = await verdict_of(cam)
            if verdict is not None and diagnostic:
                print(f"topgimbal: warning: {verdict.message}", file=sys.stderr, flush=True)
            elif verdict is not None:  # the answer was read through the wrong model: not shown
                raise TopGimbalError(f"{verdict.message}; the answer is not shown: it was read as a {cam.model.name}'s")
            return result

    started = monotonic()
    try:
        with model_check_records_left_out():
            result = asyncio.run(main())
    except RequestTimeoutError as exc:
        # The message counts one request's attempts; say how long the whole command waited.
        raise RequestTimeoutError(f"{exc} [{monotonic() - started:.1f} s since the command started]") from None
    except TimeoutError as exc:  # a bare asyncio timeout has no message: never print an empty error
        raise RequestTimeoutError(
            f"the device at {args.url} did not answer in time ({exc or 'no reply'}); "
            "check --url, --model and that the camera is on"
        ) from None
    if isinstance(result, int):
        return result
    show(args, result)
    return 0


# -- commands ------------------------------------------------------------------------------------


async def _info(cam: AsyncClient, args: argparse.Namespace) -> dict[str, object]:
    ident = await cam.identify()
    return {**ident, "url": cam.url, "title": cam.model.title, "link": cam.stats.as_dict()}


DIAGNOSTICS: set[Runner] = {_info}  # commands that show what the device is, whatever --model says


async def _attitude(cam: AsyncClient, args: argparse.Namespace) -> dict[str, object] | int:
    if not args.watch:
        return attitude_dict(await cam.get_attitude())
    n = 0
    async for att in cam.attitude(rate_hz=args.rate):
        d = attitude_dict(att)
        if args.json:
            print(dumps(d), flush=True)
        else:
            print(f"yaw {d['yaw_deg']:8.2f}  pitch {d['pitch_deg']:8.2f}  roll {d['roll_deg']:8.2f}", flush=True)
        n += 1
        if args.count and n >= args.count:
            break
    return 0


async def _stop(cam: AsyncClient, args: argparse.Namespace) -> dict[str, object]:
    await cam.stop()
    return ok("stop")


async def _center(cam: AsyncClient, args: argparse.Namespace) -> dict[str, object]:
    await cam.center()
    return ok("center")


async def _mode(cam: AsyncClient, args: argparse.Namespace) -> dict[str, object]:
    await cam.set_mode(args.mode)
    return ok("mode", mode=args.mode)


async def _zoom(cam: AsyncClient, args: argparse.Namespace) -> dict[str, object]:
    try:
        magnification = float(args.value)
    except ValueError:
        pass  # a word (in, out, stop): the client names the words it knows
    else:
        if not math.isfinite(magnification):
            raise FieldValueError("zoom", args.value, "in, out, stop or a magnification such as 2")
    if args.digital:
        await cam.digital_zoom(args.value)
    else:
        await cam.zoom(args.value)
    return ok("zoom", value=args.value)


async def _focus(cam: AsyncClient, args: argparse.Namespace) -> dict[str, object]:
    await cam.focus(args.action)
    return ok("focus", value=args.action)


async def _photo(cam: AsyncClient, args: argparse.Namespace) -> dict[str, object]:
    m = await cam.photo()
    out = ok("photo")
    if m.fields and "file_index" in m.fields:
        out["file_index"] = m.fields["file_index"]
    return out


async def _record(cam: AsyncClient, args: argparse.Namespace) -> dict[str, object]:
    if args.action == "start":
        await cam.start_recording()
    elif args.action == "stop":
        await cam.stop_recording()
    elif args.action == "toggle":
        await cam.toggle_recording()
    return {"recording": await cam.recording()}


async def _sd(cam: AsyncClient, args: argparse.Namespace) -> SdCard:
    return await cam.sd_card()


async def _thermal(cam: AsyncClient, args: argparse.Namespace) -> dict[str, object]:
    value = args.value
    if value is not None:
        with contextlib.suppress(ValueError):
            value = int(value)
    result = await cam.thermal(args.setting, value)
    return {args.setting: result}


async def _range(cam: AsyncClient, args: argparse.Namespace) -> dict[str, object]:
    distance = await cam.range()
    if distance is None:
        lo, hi = cam.model.lrf_range_m or (0.0, 0.0)
        why = f"the rangefinder reported no distance (ERR): nothing between {lo:g} and {hi:g} m where it points"
        if role_ident(cam.dialect, cam.model, "altitude") is not None:
            why += (
                f". The {cam.model.name} (and the simulator) measure ground range from the vehicle altitude the "
                f"host sends (ALT): send it first, e.g. `topgimbal --url {cam.url} --model {cam.model.name} "
                "command ALT alt_m=120`, then point the camera below the horizon"
            )
        raise TopGimbalError(why)
    return {"range_m": distance}


async def _net(cam: AsyncClient, args: argparse.Namespace) -> Mapping[str, object]:
    if args.action == "show":
        return await cam.network()
    changes = {k: v for k, v in (("ip", args.ip), ("gateway", args.gateway), ("dns", args.dns)) if v is not None}
    if args.backup_dns is not None:
        changes["backup_dns"] = args.backup_dns
    if not changes:
        raise TopGimbalError("net set: nothing to change (give --ip, --gateway, --dns or --backup-dns)")
    if not args.yes:
        summary = ", ".join(f"{k}={v}" for k, v in changes.items())
        if not sys.stdin.isatty():
            raise TopGimbalError(f"net set {summary}: refusing without confirmation (pass --yes)")
        answer = input(f"Change the camera's network settings ({summary})? The camera may move. [y/N] ")
        if answer.strip().lower() not in ("y", "yes"):
            raise TopGimbalError("net set: not confirmed")
    for ident_name in changes:
        cam.build(
            {"ip": "IPV", "gateway": "GTW", "dns": "DNS", "backup_dns": "BNS"}[ident_name], address=changes[ident_name]
        )
    await cam.set_network(**changes)
    return ok("net set", **changes)


async def _raw(cam: AsyncClient, args: argparse.Namespace) -> dict[str, object]:
    """A frame as given; without its checksum it is completed (as the console does)."""
    reply = await cam.send_raw(args.frame, wait_reply=not args.no_wait)
    if reply is None:
        return ok("raw")
    return {"reply": reply.frame.text(), **reply.to_dict()}


async def _command_generic(cam: AsyncClient, args: argparse.Namespace) -> dict[str, object]:
    spec = cam.dialect.command(args.ident)
    values: dict[str, FieldValue] = {}
    forms = spec.forms_for("r" if args.read else "w", "request")
    codecs = {f.name: f.codec for form in forms for f in form.fields}
    for item in args.values:
        if "=" not in item:
            raise TopGimbalError(f"{item!r}: give values as name=value ({', '.join(codecs) or 'no fields'})")
        k, v = item.split("=", 1)
        codec = codecs.get(k)
        values[k] = codec.parse_text(v) if codec is not None and hasattr(codec, "parse_text") else v
    # request()'s own keywords are not field names here: the values go to the frame as given
    m = await cam.send_request(cam.build_from(spec.ident, values, read=args.read))
    return {"reply": m.frame.text(), **m.to_dict()}


# -- registration --------------------------------------------------------------------------------


def register(sub: argparse._SubParsersAction) -> None:
    _command(sub, "info", _info, "identify the device: dialect, model, version, link statistics")

    p = _command(sub, "attitude", _attitude, "print the gimbal attitude (degrees; yaw right-, pitch up-positive)")
    p.add_argument("--watch", action="store_true", help="stream samples until interrupted (or --count)")
    p.add_argument("--rate", type=HZ, default=10.0, help="--watch sample rate in Hz (default 10)")
    p.add_argument("--count", type=COUNT, default=0, help="--watch: stop after N samples (default 0: never)")

    device_motion.register(sub, _command, _seconds)

    _command(sub, "stop", _stop, "stop all gimbal motion")
    _command(sub, "center", _center, "centre the gimbal")
    p = _command(sub, "mode", _mode, "gimbal mode: follow or lock")
    p.add_argument("mode", choices=["follow", "lock"])

    p = _command(sub, "zoom", _zoom, "zoom: in | out | stop | a magnification")
    p.add_argument("value", help="in, out, stop or a magnification such as 2")
    p.add_argument("--digital", action="store_true", help="digital zoom (DZM)")
    actions = list(dict.fromkeys(a for name in DIALECT_NAMES for a in focus_actions(get_dialect(name))))
    p = _command(sub, "focus", _focus, "focus: " + " | ".join(actions))
    p.add_argument("action", help=", ".join(actions))

    _command(sub, "photo", _photo, "take a photo")
    p = _command(sub, "record", _record, "recording: start | stop | status | toggle")
    p.add_argument("action", choices=["start", "stop", "status", "toggle"])
    _command(sub, "sd", _sd, "SD card presence and capacity")
    p = _command(sub, "thermal", _thermal, "read or set a thermal setting: thermal palette [ironbow]")
    p.add_argument("setting", help="palette, scene, shutter, detail, brightness, contrast, gamma, ...")
    p.add_argument("value", nargs="?", default=None)
    _command(sub, "range", _range, "one laser range measurement (metres)")
    locate_cmd.register(sub, _command)  # topgimbal locate (the geo package)

    p = _command(sub, "net", _net, "network settings: show | set (asks for confirmation)")
    p.add_argument("action", choices=["show", "set"])
    p.add_argument("--ip")
    p.add_argument("--gateway")
    p.add_argument("--dns")
    p.add_argument("--backup-dns", dest="backup_dns")
    p.add_argument("--yes", action="store_true", help="do not ask for confirmation")

    p = _command(sub, "raw", _raw, "send one frame as given and print the decoded reply")
    p.add_argument("frame", help="e.g. '#TPUD2rREC003E', or without its checksum '#TPUD2rREC00' (quote the #)")
    p.add_argument("--no-wait", action="store_true", help="do not wait for a reply")

    p = _command(sub, "command", _command_generic, "send any catalog command: command GAY yaw_deg=10")
    p.add_argument("ident", help="identifier or catalog name")
    p.add_argument("values", nargs="*", help="name=value (user units)")
    p.add_argument("--read", action="store_true", help="send the query form")
    device_session.register(sub, _command)
