"""Arguments shared by every subcommand (python-can's add_bus_arguments pattern)."""

from __future__ import annotations

import argparse
import os
from typing import Any

from ..protocol import DIALECT_NAMES, all_models


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
        help="device model; picks the dialect, limits and wire signs (env TOPGIMBAL_MODEL)",
    )


def add_camera_subcommand(
    subparsers: argparse._SubParsersAction[argparse.ArgumentParser],
    name: str,
    *,
    model_help: str = "device model (picks the dialect)",
    **kwargs: Any,
) -> argparse.ArgumentParser:
    """A subcommand that talks to one camera, with its own `--url` and `--model`: they also exist
    on the main parser, and SUPPRESS keeps a value given there."""
    parser = subparsers.add_parser(name, **kwargs)
    parser.add_argument("--url", default=argparse.SUPPRESS, help="camera address, e.g. udp://HOST:5000")
    add_model_argument(parser, default=argparse.SUPPRESS, help=model_help)
    return parser


def add_model_argument(parser: argparse.ArgumentParser, flag: str = "--model", **kwargs: Any) -> None:
    """A model name option, matched case-insensitively against the catalog's models."""
    parser.add_argument(flag, type=_model_name, choices=sorted(all_models(), key=str.lower), **kwargs)


def accept_connection_arguments_after(command: argparse.ArgumentParser) -> None:
    """`topgimbal proxy --model C12 ...` as well as `topgimbal --model C12 proxy ...`: the global
    `--url` / `--model` also after the command (unless the command has its own). Given there, they
    replace the global value; not given, they leave it (SUPPRESS: no default of their own)."""
    taken = {opt for action in command._actions for opt in action.option_strings}
    after = " (also accepted before the command)"
    if "--url" not in taken:
        command.add_argument("--url", default=argparse.SUPPRESS, help=f"camera address, e.g. udp://HOST:5000{after}")
    if "--model" not in taken:
        add_model_argument(command, default=argparse.SUPPRESS, help=f"device model{after}")


def _model_name(text: str) -> str:
    for name in all_models():
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
