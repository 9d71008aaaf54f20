"""The CLI's fast dispatch (cli/main.py `parse`: a first look at the command word, else a parse with
placeholders, then the chosen module's parser) reads every command line as the whole parser does."""

from __future__ import annotations

import contextlib
import io

import pytest

from topgimbal.cli import main
from topgimbal.cli.command_index import COMMANDS

pytestmark = pytest.mark.loopback

LINES = [
    ["decode", "#TPUG6wGAYEC78324D"],
    ["--url", "udp://127.0.0.1:9", "decode", "--json", "X"],
    ["--model", "C12", "encode", "GAY", "yaw_deg=1"],
    ["--mod", "c12", "decode", "F"],  # an abbreviated global option, a model in another case
    ["--url=udp://127.0.0.1:9", "sim", "--model", "C12"],
    ["--url", "decode", "decode", "X"],  # the command word as an option's value first
    ["decode", "--", "-X"],
    ["--model", "C12", "--", "decode"],
    ["decode", "--pcap", "x.pcap", "--address", "::1", "--port", "5000"],
    ["decode", "--address", "not-an-address", "--pcap", "x.pcap"],
    ["--model", "C99", "decode", "X"],
    ["decod", "X"],
    ["info", "--model", "C13"],
    ["proxy", "--model", "C12", "--listen", "udp://127.0.0.1:0", "--to", "udp://127.0.0.1:9"],
    ["catalog", "GAY", "--dialect", "topotek"],
    ["decode", "--help"],
    [],
]


def _outcome(parse: object, argv: list[str]) -> tuple[object, ...]:
    out, err = io.StringIO(), io.StringIO()
    with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
        try:
            args = parse(argv)  # type: ignore[operator]
        except SystemExit as exc:
            return ("exit", exc.code, out.getvalue(), err.getvalue())
    named = {k: (v.__module__, v.__qualname__) if callable(v) else v for k, v in vars(args).items()}
    return ("args", named)  # a command's `func` may be a closure made at each registration: by name


@pytest.mark.parametrize("argv", LINES, ids=lambda a: " ".join(a) or "(none)")
def test_the_fast_dispatch_reads_a_command_line_as_the_whole_parser_does(
    argv: list[str], monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.delenv("TOPGIMBAL_URL", raising=False)
    monkeypatch.delenv("TOPGIMBAL_MODEL", raising=False)
    fast = _outcome(lambda a: main.parse(a)[1], argv)
    whole = _outcome(lambda a: main.build_parser().parse_args(a), argv)
    if fast[0] == "args" and whole[0] == "args":
        got, want = dict(fast[1]), dict(whole[1])  # type: ignore[call-overload]
        assert got == want
    else:
        assert fast[:2] == whole[:2]  # the same exit status
        if fast[1] == 2:  # a usage error names the same problem
            assert fast[3].splitlines()[-1] == whole[3].splitlines()[-1]


@pytest.mark.parametrize(
    ("argv", "word"),
    [
        (["decode", "X"], "decode"),
        (["--url", "decode", "decode", "X"], "decode"),
        (["--model", "C12", "encode", "GAY"], "encode"),
        (["-h", "decode"], None),  # --help first: the top-level help, with every command
        (["--model", "C99", "decode"], None),  # a bad global option: the placeholder parser says so
        (["decod"], None),
        (["--model", "C12", "--", "decode"], None),
        ([], None),
    ],
)
def test_the_first_look_names_a_plain_command_and_leaves_the_rest(argv: list[str], word: str | None) -> None:
    assert main._command_word(argv) == word
    assert word is None or word in COMMANDS
