"""Arguments shared by every subcommand (python-can's add_bus_arguments pattern)."""

from __future__ import annotations

import argparse
import os

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
    parser.add_argument(
        "--model",
        default=os.environ.get("TOPGIMBAL_MODEL"),
        choices=sorted(all_models(), key=str.lower),
        type=_model_name,
        help="device model; picks the dialect, limits and wire signs (env TOPGIMBAL_MODEL)",
    )


def accept_connection_arguments_after(top: argparse.ArgumentParser, command: argparse.ArgumentParser) -> None:
    """`topgimbal proxy --model C12 ...` as well as `topgimbal --model C12 proxy ...`: the global
    `--url` / `--model` also after the command (unless the command has its own). Given there, they
    replace the global value; not given, they leave it (SUPPRESS: no default of their own)."""
    taken = {opt for action in command._actions for opt in action.option_strings}
    for action in top._actions:
        if action.dest not in ("url", "model") or taken.intersection(action.option_strings):
            continue
        extra: dict[str, object] = {"choices": action.choices, "type": action.type} if action.dest == "model" else {}
        command.add_argument(
            *action.option_strings,
            dest=action.dest,
            default=argparse.SUPPRESS,
            help=f"{action.help} (also accepted before the command)",
            **extra,  # type: ignore[arg-type]
        )


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
