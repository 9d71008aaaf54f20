"""Entry point: builds the parser from the subcommand modules and runs the chosen one.

Each module in COMMAND_MODULES has `register(subparsers)`; each subparser sets `func(args) -> int`.
Errors from topgimbal end as one line on stderr and a non-zero exit code: 2 when the input was
refused before anything was sent (a value out of the model's range, an unknown command, a command
the model lacks: CatalogError; a --model the device contradicts: ModelMismatchError; a bad --url or endpoint: InputError), 1 when the device, the link or a file failed.

Starting fast: `main()` does not import every command module. `command_index.py` (generated from
the real parsers by `python -m topgimbal.tools.regen`) names the module and the one-line help of
every subcommand; `main()` first parses with placeholders built from it (enough for `--help` and to
find the command), then registers only the chosen command's module and parses again. A module
missing from the index is registered every time (correct, only slower) until the index is
regenerated; the regeneration check fails meanwhile."""

from __future__ import annotations

import argparse
import importlib
import importlib.util
import os
import sys
from collections.abc import Sequence
from typing import NoReturn

from ..errors import CatalogError, InputError, ModelMismatchError, TopGimbalError
from . import args as common
from .command_index import COMMANDS

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
    "video_cmd",
    "track_cmd",
)


def build_parser(only: str | None = None) -> argparse.ArgumentParser:
    """The whole parser. With `only=""`, every indexed subcommand as a placeholder (its name and
    help); with `only` a module of COMMAND_MODULES, that module's subcommands alone (and any module
    the index does not know yet)."""
    parser = argparse.ArgumentParser(
        prog="topgimbal",
        description="Control and simulate TOP-protocol gimbal cameras (TOPOTEK SIP, SkyDroid C10..C20).",
    )
    common.add_connection_arguments(parser)
    sub = parser.add_subparsers(dest="command", metavar="COMMAND")
    indexed = {module for module, _ in COMMANDS.values()}
    for name in COMMAND_MODULES:
        if only is not None and name != only and name in indexed:
            if only:  # the command is known to be `only`'s: the others need not even be named
                continue
            for cmd, (module, help_text) in COMMANDS.items():
                if module == name:
                    _placeholder(sub, cmd, module, help_text)
            continue
        modname = f"{__package__}.{name}"
        if importlib.util.find_spec(modname) is None:
            continue  # subcommand not shipped in this build
        importlib.import_module(modname).register(sub)
    for parser_ in sub.choices.values():
        if parser_.get_default("lazy_module") is None:
            common.accept_connection_arguments_after(parser_)
    return parser


def _placeholder(sub: argparse._SubParsersAction, command: str, module: str, help_text: str | None) -> None:
    """A subcommand known from the index: takes anything, says which module to load for it."""
    p = sub.add_parser(command, help=help_text, add_help=False, prefix_chars="\0")
    p.add_argument("rest", nargs=argparse.REMAINDER)
    p.set_defaults(lazy_module=module)


class _NotSureError(Exception):
    """The first look at a command line found something it leaves to the real parsers."""


class _FirstLook(argparse.ArgumentParser):
    def error(self, message: str) -> NoReturn:
        raise _NotSureError(message)


def _command_word(argv: list[str]) -> str | None:
    """The indexed subcommand `argv` names, read by one parser of the global options (a placeholder
    per subcommand costs more than the command's own parser). None whenever it is not plain (no
    command, an unknown word, `--help`, a bad global option): the placeholder parse then decides,
    and says what is wrong, as before."""
    first = _FirstLook(prog="topgimbal", add_help=False)
    common.add_connection_arguments(first)
    first.add_argument("command", nargs="?")
    first.add_argument("rest", nargs=argparse.REMAINDER)
    try:
        args, unknown = first.parse_known_args(argv)
    except _NotSureError:
        return None
    before = argv[: len(argv) - len(args.rest)]  # up to the command word: `--` there is left to argparse
    return args.command if not unknown and args.command in COMMANDS and "--" not in before else None


def parse(argv: Sequence[str] | None) -> tuple[argparse.ArgumentParser, argparse.Namespace]:
    """Find the command (`_command_word`, else a parse with placeholders), then parse again with the
    chosen command's module registered."""
    argv = common.join_negative_values(list(sys.argv[1:] if argv is None else argv))
    word = _command_word(argv)
    module: str | None
    if word is not None:
        module = COMMANDS[word][0]
    else:
        parser = build_parser(only="")
        args = parser.parse_args(argv)
        module = getattr(args, "lazy_module", None)
        if module is None:
            return parser, args  # no command, or one whose module is not in the index (registered)
    parser = build_parser(only=module)
    return parser, parser.parse_args(argv)


def main(argv: Sequence[str] | None = None) -> int:
    parser, args = parse(argv)
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
    except (CatalogError, ModelMismatchError, InputError) as exc:  # refused before anything was sent: the input
        print(f"topgimbal: error: {exc}", file=sys.stderr)
        return USAGE_ERROR
    except (TopGimbalError, ValueError, OSError) as exc:
        print(f"topgimbal: error: {exc}", file=sys.stderr)
        return 1


def index_text() -> str:
    """`command_index.py` as the registered parsers say it should be (tools/regen.py writes it)."""
    import json

    from ..protocol import dialects

    sub = next(a for a in build_parser()._actions if isinstance(a, argparse._SubParsersAction))
    helps = {action.dest: action.help for action in sub._choices_actions}
    owner: dict[str, str] = {}
    for name in COMMAND_MODULES:
        modname = f"{__package__}.{name}"
        if importlib.util.find_spec(modname) is None:
            continue
        probe = argparse.ArgumentParser().add_subparsers()
        importlib.import_module(modname).register(probe)
        owner.update(dict.fromkeys(probe.choices, name))
    rows = "".join(f"    {json.dumps(c)}: ({json.dumps(owner[c])}, {json.dumps(helps.get(c))}),\n" for c in sub.choices)
    return (
        '"""Generated by `python -m topgimbal.tools.regen` from the CLI\'s parsers (do not edit): the module\n'
        "that registers each subcommand and its one-line help, so `topgimbal --help` and a command start\n"
        'without importing every command module (cli/main.py)."""\n\n'
        "from __future__ import annotations\n\n"
        "# fmt: off\n"
        f"COMMANDS: dict[str, tuple[str, str | None]] = {{\n{rows}}}\n"
        f"MODEL_NAMES = {json.dumps(dialects.model_names())}\n"
        f"DIALECT_NAMES = {json.dumps(list(dialects.DIALECT_NAMES))}\n"
        "# fmt: on\n"
    ).replace(": null)", ": None)")


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
