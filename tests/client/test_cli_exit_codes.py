"""Exit codes and one-line errors (issue 35.4): an unusable --url, a missing --url and a bad
--mavlink endpoint are input refused before anything is sent: exit 2, one line. Nothing at the port
says so once."""

from __future__ import annotations

import os
import socket
import subprocess
import sys
from pathlib import Path

import pytest

import topgimbal
from topgimbal.cli.main import main
from topgimbal.errors import AddressError, InputError, TransportError

pytestmark = pytest.mark.loopback


@pytest.mark.parametrize(
    ("url", "said"),
    [
        ("127.0.0.1:5000", "must look like udp://HOST:PORT"),
        ("http://127.0.0.1:5000", "unknown scheme 'http'"),
        ("udp://127.0.0.1:99999", "out of range"),
        ("udp://:5000", "needs a host and a port"),
    ],
)
def test_an_unusable_url_exits_2_in_one_line(capsys, url: str, said: str) -> None:
    assert main(["--url", url, "--model", "C12", "attitude"]) == 2
    err = capsys.readouterr().err
    assert len(err.splitlines()) == 1 and said in err and err.startswith("topgimbal: error: "), err


def test_the_python_error_is_an_address_error_and_still_a_transport_error() -> None:
    with pytest.raises(AddressError) as info:
        topgimbal.connect("http://127.0.0.1:5000")
    assert isinstance(info.value, TransportError) and isinstance(info.value, InputError)


def test_a_missing_url_exits_2(capsys, monkeypatch) -> None:
    monkeypatch.delenv("TOPGIMBAL_URL", raising=False)
    assert main(["--model", "C12", "attitude"]) == 2
    err = capsys.readouterr().err
    assert len(err.splitlines()) == 1 and "--url" in err


def test_a_bad_mavlink_endpoint_exits_2(capsys) -> None:
    assert main(["mavlink", "--url", "udp://127.0.0.1:5000", "--model", "C12", "--mavlink", "foo:bar"]) == 2
    err = capsys.readouterr().err
    assert len(err.splitlines()) == 1 and "'foo:bar': not a MAVLink endpoint" in err


def test_nothing_at_the_port_is_said_once() -> None:
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as quiet:  # bound, never answers
        quiet.bind(("127.0.0.1", 0))
        url = f"udp://127.0.0.1:{quiet.getsockname()[1]}"
        env = dict(os.environ, PYTHONPATH=str(Path(topgimbal.__file__).parents[1]))
        out = subprocess.run([sys.executable, "-m", "topgimbal.cli.main", "--url", url, "--model", "C12", "attitude"],
                             capture_output=True, text=True, timeout=120, env=env)  # fmt: skip
    assert out.returncode == 1
    lines = out.stderr.splitlines()
    # one line naming the address; the wording is that of whichever noticed first (NoAnswerError: the
    # link monitor's "not answered", or the request's timeout, "nothing at all has come from ...")
    assert len(lines) == 1 and url in lines[0], out.stderr
    assert "not answered" in lines[0] or "nothing at all has come" in lines[0], out.stderr
