"""Entry point: builds the parser from the subcommand modules and runs the chosen one.

Each module in COMMAND_MODULES has `register(subparsers)`; each subparser sets `func(args) -> int`.
Errors from topgimbal end as one line on stderr and a non-zero exit code: 2 when the input was
refused before anything was sent (a value out of the model's range, an unknown command, a command
the model lacks: CatalogError), 1 when the device, the link or a file failed."""

from __future__ import annotations

import argparse
import importlib
import importlib.util
import os
import sys
from collections.abc import Sequence

from ..errors import CatalogError, TopGimbalError
from . import args as common

USAGE_ERROR = 2  # as argparse exits for a malformed command line: the input, not the device, was wrong
COMMAND_MODULES = (
    "protocol_cmds",
    "sim_cmd",
    "device_cmds",
    "console_cmd",
    "mavlink_cmd",
    "wire_cmds",
    "media_cmd",
    "geotag_cmd",
    "zenoh_cmd",
)


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="topgimbal",
        description="Control and simulate TOP-protocol gimbal cameras (TOPOTEK SIP, SkyDroid C10..C20).",
    )
    common.add_connection_arguments(parser)
    sub = parser.add_subparsers(dest="command", metavar="COMMAND")
    for name in COMMAND_MODULES:
        modname = f"{__package__}.{name}"
        if importlib.util.find_spec(modname) is None:
            continue  # subcommand not shipped in this build
        importlib.import_module(modname).register(sub)
    for command in sub.choices.values():
        common.accept_connection_arguments_after(command)
    return parser


def main(argv: Sequence[str] | None = None) -> int:
    parser = build_parser()
    args = parser.parse_args(argv)
    if not getattr(args, "func", None):
        parser.print_help()
        return 2
    try:
        code = int(args.func(args) or 0)
        sys.stdout.flush()  # a closed pipe shows here, not at exit
        return code
    except KeyboardInterrupt:  # Ctrl-C: say so, a bare 130 reads as a crash in a script's log
        print("topgimbal: interrupted", file=sys.stderr)
        return 130
    except BrokenPipeError:  # the reader left (`| head`): not an error of ours
        os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())
        return 0
    except CatalogError as exc:  # refused before anything was sent: a value, command or model the user gave
        print(f"topgimbal: error: {exc}", file=sys.stderr)
        return USAGE_ERROR
    except (TopGimbalError, ValueError, OSError) as exc:
        print(f"topgimbal: error: {exc}", file=sys.stderr)
        return 1


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
