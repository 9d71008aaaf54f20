"""Arguments shared by every subcommand (python-can's add_bus_arguments pattern)."""

from __future__ import annotations

import argparse
import contextlib
import math
import os
import stat
from collections.abc import Callable
from typing import TYPE_CHECKING, Any

from ..errors import TopGimbalError
from .command_index import DIALECT_NAMES, MODEL_NAMES

if TYPE_CHECKING:
    from ..protocol import Dialect

# Model and dialect names come from the generated index (tools/regen.py checks them against the
# catalog), so building a parser does not import the protocol core (cli/main.py: a fast start).
# For the same reason pathlib and ipaddress are imported by the functions that use them: every
# command builds its parser, few read a path.


def add_connection_arguments(parser: argparse.ArgumentParser) -> None:
    """`--url`, `--model` (and `--dialect` for the offline commands). Environment variables
    TOPGIMBAL_URL and TOPGIMBAL_MODEL give defaults, so scripts need not repeat them."""
    parser.add_argument(
        "--url",
        default=os.environ.get("TOPGIMBAL_URL"),
        help="camera address: udp://HOST:PORT, tcp://HOST:PORT or serial:///dev/ttyUSB0?baud=115200 "
        "(env TOPGIMBAL_URL)",
    )
    add_model_argument(
        parser,
        default=os.environ.get("TOPGIMBAL_MODEL"),
        help="device model; picks the dialect, limits and wire signs; auto: ask the device (env TOPGIMBAL_MODEL)",
        auto=True,
    )


def add_camera_subcommand(
    subparsers: argparse._SubParsersAction[argparse.ArgumentParser],
    name: str,
    *,
    model_help: str = "device model (picks the dialect)",
    auto: bool = False,
    **kwargs: Any,
) -> argparse.ArgumentParser:
    """A subcommand that talks to one camera, with its own `--url` and `--model`: they also exist
    on the main parser, and SUPPRESS keeps a value given there."""
    parser = subparsers.add_parser(name, **kwargs)
    parser.add_argument("--url", default=argparse.SUPPRESS, help="camera address, e.g. udp://HOST:5000")
    add_model_argument(parser, default=argparse.SUPPRESS, help=model_help, auto=auto)
    return parser


def add_model_argument(parser: argparse.ArgumentParser, flag: str = "--model", *, auto: bool = False,
                       **kwargs: Any) -> None:  # fmt: skip
    """A model name option, matched case-insensitively against the catalog's models; `auto`: also
    the word auto (ask the device what it is, for the commands that talk to one)."""
    names = sorted(MODEL_NAMES, key=str.lower) + (["auto"] if auto else [])
    parser.add_argument(flag, type=_model_name, choices=names, **kwargs)


def accept_connection_arguments_after(command: argparse.ArgumentParser) -> None:
    """`topgimbal proxy --model C12 ...` as well as `topgimbal --model C12 proxy ...`: the global
    `--url` / `--model` also after the command (unless the command has its own). Given there, they
    replace the global value; not given, they leave it (SUPPRESS: no default of their own)."""
    taken = {opt for action in command._actions for opt in action.option_strings}
    after = " (also accepted before the command)"
    if "--url" not in taken:
        command.add_argument("--url", default=argparse.SUPPRESS, help=f"camera address, e.g. udp://HOST:5000{after}")
    if "--model" not in taken:
        add_model_argument(command, default=argparse.SUPPRESS, help=f"device model, or auto{after}", auto=True)


def _model_name(text: str) -> str:
    for name in [*MODEL_NAMES, "auto"]:
        if name.lower() == text.lower():
            return name
    return text  # argparse's `choices` reports the error with the list


def add_dialect_argument(parser: argparse.ArgumentParser, *, auto: bool = True) -> None:
    choices = [*DIALECT_NAMES, "auto"] if auto else list(DIALECT_NAMES)
    parser.add_argument(
        "--dialect",
        choices=choices,
        default="auto" if auto else None,
        required=not auto,
        help="protocol dialect (auto: from --model, else try both)",
    )


def add_json_argument(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--json", action="store_true", help="machine-readable JSON output")


def add_pcap_arguments(p: argparse.ArgumentParser) -> None:
    """The options `decode` gains for captures (`decode --pcap` runs in cli/wire_cmds.py, with the
    other capture tools; declared here so that a plain `decode` does not import that module)."""
    p.add_argument("--pcap", metavar="FILE", help="decode every frame in a pcap/pcapng capture, in time order")
    p.add_argument("--port", type=int, action="append", metavar="N", help="with --pcap: only this port (repeatable)")
    p.add_argument(
        "--address", type=ip_address, action="append", metavar="IP", help="with --pcap: only this address (repeatable)"
    )


def ip_address(text: str) -> str:
    """argparse type: an IPv4 or IPv6 address, in its normal spelling."""
    import ipaddress

    try:
        return str(ipaddress.ip_address(text))
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text!r} is not an IPv4 or IPv6 address") from None


# -- number types: a bad value is a usage error (exit 2) naming what is allowed -------------------


def number(
    *, low: float | None = None, high: float | None = None, low_open: bool = False, what: str = "a number"
) -> Callable[[str], float]:
    """argparse type: a finite float within low..high (`low_open`: above low, not equal). NaN and
    infinity are refused: a wait of nan seconds or a rate of inf Hz is never what was meant."""

    def parse(text: str) -> float:
        try:
            value = float(text)
        except ValueError:
            value = math.nan
        too_low = low is not None and (value <= low if low_open else value < low)
        if not math.isfinite(value) or too_low or (high is not None and value > high):
            raise argparse.ArgumentTypeError(f"{text!r} is not {what}: expected {_span(low, high, low_open)}")
        return value

    return parse


def whole(*, low: int = 0, high: int | None = None, what: str = "a count") -> Callable[[str], int]:
    """argparse type: a whole number within low..high."""

    def parse(text: str) -> int:
        try:
            value = int(text)
        except ValueError:
            raise argparse.ArgumentTypeError(f"{text!r} is not {what}: expected a whole number") from None
        if value < low or (high is not None and value > high):
            raise argparse.ArgumentTypeError(f"{text!r} is not {what}: expected {_span(low, high, False)}")
        return value

    return parse


def _span(low: float | None, high: float | None, low_open: bool) -> str:
    if low is None and high is None:
        return "a finite number"
    if high is None:
        return f"a number above {low:g}" if low_open else f"a number {low:g} or more"
    if low is None:
        return f"a number up to {high:g}"
    return f"a number above {low:g} and up to {high:g}" if low_open else f"{low:g}..{high:g}"


HZ = number(low=0, low_open=True, what="a rate in Hz")
COUNT = whole(low=0, what="a count")


def input_file(path: str, what: str) -> str:
    """`path` when it is a regular file that can be read. A FIFO or a device would block the
    command at open() (a FIFO with no writer waits for ever) or stream without end: refused."""
    try:
        mode = os.stat(path).st_mode
    except OSError as exc:
        raise FileArgumentError(f"{what} {path}: {exc.strerror or exc}") from None
    if not stat.S_ISREG(mode):
        kind = "a directory" if stat.S_ISDIR(mode) else "a FIFO" if stat.S_ISFIFO(mode) else "not a regular file"
        raise FileArgumentError(f"{what} {path} is {kind}: give a regular file")
    return path


def writable_output(path: str, what: str = "output file") -> str:
    """`path` when a file can be written there, checked before the work that fills it (nothing is
    created here: a command that then fails leaves no empty file behind)."""
    from pathlib import Path

    p = Path(path)
    if p.is_dir():
        raise FileArgumentError(f"{what} {path} is a directory: give a file path")
    parent = p.parent
    if not parent.is_dir():
        raise FileArgumentError(f"{what} {path}: the directory {parent} does not exist")
    if not os.access(parent, os.W_OK) or (p.exists() and not os.access(p, os.W_OK)):
        raise FileArgumentError(f"{what} {path} cannot be written (permission denied)")
    return path


def write_whole(path: str, text: str) -> None:
    """Write `text` to `path` all or nothing: a failure (disk full, interrupted) leaves the old
    file as it was, never a truncated one."""
    import tempfile  # here: it loads shutil, random and the compressors, which `--help` need not
    from pathlib import Path

    writable_output(path)
    fd, tmp = tempfile.mkstemp(dir=Path(path).parent, prefix=f".{Path(path).name}.", suffix=".tmp")
    try:
        with os.fdopen(fd, "w", encoding="utf-8") as fh:
            fh.write(text)
        os.replace(tmp, path)
    except BaseException:
        with contextlib.suppress(OSError):
            os.unlink(tmp)
        raise


class FileArgumentError(TopGimbalError, OSError):
    """A file given on the command line cannot be used as asked (missing, a directory, a FIFO, a
    directory that does not exist for an output)."""


def dialect_from_args(args: argparse.Namespace) -> Dialect | None:
    """The dialect `--dialect` names, else `--model`'s, else None (decide per frame)."""
    from ..protocol import get_dialect, get_model

    if getattr(args, "dialect", "auto") not in (None, "auto"):
        return get_dialect(args.dialect)
    if getattr(args, "model", None):
        return get_model(args.model)[0]
    return None


# -- coordinates --------------------------------------------------------------------------------

# A comma list of numbers that starts with a minus: a southern latitude (`-35.36,149.16,600`).
# argparse takes any word that starts with "-" and is not a plain number for an option, so
# `--position -35.36,149.16,600` failed with "expected one argument" (issue 41 item 10).
_NEGATIVE_LIST = r"-(?:\d+\.?\d*|\.\d+)(?:[eE][-+]?\d+)?(?:,\s*[-+]?(?:\d+\.?\d*|\.\d+)(?:[eE][-+]?\d+)?)+"


def join_negative_values(argv: list[str]) -> list[str]:
    """`--opt -35.36,149.16` becomes `--opt=-35.36,149.16`, which argparse reads as written. Only a
    comma list of numbers after a long option is joined: no option looks like that, and the
    `=` form is argparse's own (documented) way to give a value that starts with "-"."""
    import re

    out: list[str] = []
    i = 0
    while i < len(argv):
        word = argv[i]
        nxt = argv[i + 1] if i + 1 < len(argv) else None
        if word == "--":
            out.extend(argv[i:])  # after `--` everything is positional, as argparse has it
            break
        if (
            nxt is not None
            and word.startswith("--")
            and "=" not in word
            and len(word) > 2
            and re.fullmatch(_NEGATIVE_LIST, nxt)
        ):
            out.append(f"{word}={nxt}")
            i += 2
            continue
        out.append(word)
        i += 1
    return out


def _numbers(text: str, names: tuple[str, ...]) -> tuple[float, ...]:
    form = ",".join(n.upper() for n in names)
    parts = [p.strip() for p in text.split(",")]
    if len(parts) != len(names):
        raise argparse.ArgumentTypeError(f"{text!r}: give {form}")
    try:
        values = tuple(float(p) for p in parts)
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text!r}: give {form} (numbers)") from None
    if not all(math.isfinite(v) for v in values):
        raise argparse.ArgumentTypeError(f"{text!r}: give {form} (finite numbers)")
    lat, lon = values[0], values[1]
    if not (-90 <= lat <= 90 and -180 <= lon <= 180):
        raise argparse.ArgumentTypeError(f"{text!r}: latitude -90..90, longitude -180..180 degrees")
    return values


def lat_lon(text: str) -> tuple[float, float]:
    """argparse type for LAT,LON in degrees (south and west negative)."""
    lat, lon = _numbers(text, ("lat", "lon"))
    return lat, lon


def lat_lon_alt(text: str) -> tuple[float, float, float]:
    """argparse type for LAT,LON,ALT: degrees, degrees, metres (south and west negative)."""
    lat, lon, alt = _numbers(text, ("lat", "lon", "alt"))
    return lat, lon, alt


# The types a test walks the parser for: every option taking coordinates uses one of these.
COORDINATE_TYPES: tuple[Callable[[str], Any], ...] = (lat_lon, lat_lon_alt)
