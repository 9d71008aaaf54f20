"""Southern and western coordinates on the command line (issue 41 item 10): every option that
takes LAT,LON[,ALT] takes negative values as written (`--position -35.36,149.16,600`, which
argparse alone refuses with "expected one argument"), through one shared type."""

from __future__ import annotations

import argparse
from collections.abc import Iterator

import pytest

from topgimbal.cli import args as cli_args
from topgimbal.cli import main as cli_main

pytestmark = pytest.mark.virtual


def _coordinate_options() -> Iterator[tuple[str, argparse.Action]]:
    """(subcommand, action) for every option of the full parser that names LAT in its metavar or
    uses a coordinate type."""
    parser = cli_main.build_parser()
    sub = next(a for a in parser._actions if isinstance(a, argparse._SubParsersAction))
    for name, p in sub.choices.items():
        for action in p._actions:
            if not action.option_strings:
                continue
            metavar = str(action.metavar or "")
            if "LAT" in metavar.upper() or action.type in cli_args.COORDINATE_TYPES:
                yield name, action


OPTIONS = sorted({(name, action.option_strings[-1]) for name, action in _coordinate_options()})


def test_the_coordinate_options_are_found() -> None:
    assert ("locate", "--position") in OPTIONS


@pytest.mark.parametrize(("command", "option"), OPTIONS)
def test_every_coordinate_option_uses_the_shared_type(command: str, option: str) -> None:
    action = next(a for n, a in _coordinate_options() if n == command and option in a.option_strings)
    assert action.type in cli_args.COORDINATE_TYPES, f"{command} {option}: not a shared coordinate type"


@pytest.mark.parametrize(("command", "option"), OPTIONS)
@pytest.mark.parametrize(("lat", "lon"), [(-35.36, 149.16), (51.5, -0.12), (-22.9, -43.2), (47.4, 8.5)])
def test_every_coordinate_option_takes_negative_values_as_written(
    command: str, option: str, lat: float, lon: float
) -> None:
    action = next(a for n, a in _coordinate_options() if n == command and option in a.option_strings)
    three = action.type is cli_args.lat_lon_alt
    text = f"{lat},{lon},600" if three else f"{lat},{lon}"
    _, args = cli_main.parse([command, option, text])
    want = (lat, lon, 600.0) if three else (lat, lon)
    assert getattr(args, action.dest) == want
    # the `=` form and the other order of words still work
    _, args = cli_main.parse([command, f"{option}={text}"])
    assert getattr(args, action.dest) == want


def test_bad_coordinates_are_a_clear_error(capsys: pytest.CaptureFixture[str]) -> None:
    for text in ("-95,10,0", "-35,200,0", "-35,10", "-35,x,0", "-35,nan,0"):
        with pytest.raises(SystemExit):
            cli_main.parse(["locate", "--position", text])
        err = capsys.readouterr().err
        assert "--position" in err and ("LAT,LON,ALT" in err or "latitude" in err), err


def test_only_number_lists_are_joined() -> None:
    join = cli_args.join_negative_values
    assert join(["locate", "--position", "-1,2,3"]) == ["locate", "--position=-1,2,3"]
    assert join(["locate", "--position", "-1.5e1,-2,3"]) == ["locate", "--position=-1.5e1,-2,3"]
    # not a number list, a single negative number (argparse reads it), or after `--`: as it was
    for argv in (["x", "--opt", "-v"], ["x", "--heading", "-30"], ["x", "--", "--opt", "-1,2"], ["x", "-p", "-1,2"]):
        assert join(argv) == argv
