"""`topgimbal sim` as a user runs it: a subprocess on loopback, stopped with SIGTERM."""

from __future__ import annotations

import json
import signal
import socket
import subprocess
import sys
from pathlib import Path

import pytest

from topgimbal.cli.main import build_parser

from .conftest import LOOP, req

pytestmark = pytest.mark.integration


def test_cli_serves_prints_endpoints_and_flushes_state_on_sigterm(tmp_path: Path) -> None:
    state = tmp_path / "s.json"
    proc = subprocess.Popen(
        [
            sys.executable,
            "-m",
            "topgimbal.cli.main",
            "sim",
            "--model",
            "sip",
            "--udp",
            f"{LOOP}:0",
            "--serial",
            "pty",
            "--state",
            str(state),
            "--seed",
            "4",
        ],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
    )
    try:
        assert proc.stdout is not None
        udp = proc.stdout.readline().strip()
        pty = proc.stdout.readline().strip()
        assert udp.startswith("udp://127.0.0.1:") and pty.startswith("serial:///dev/")
        port = int(udp.rsplit(":", 1)[1])
        with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as s:
            s.bind((LOOP, 0))
            s.settimeout(5)
            s.sendto(req("SIP", "GTW", address="10.0.0.254"), (LOOP, port))
            assert b"GTW10.0.0.254" in s.recv(100)
    finally:
        proc.send_signal(signal.SIGTERM)
        assert proc.wait(10) == 0
    assert json.loads(state.read_text())["state"]["network"]["gateway"] == "10.0.0.254"


@pytest.mark.parametrize(
    ("argv", "message"),
    [
        (["sim", "--model", "C99"], "'C99' is not a model; known: C10"),
        (["sim", "--udp", "nowhere"], "'nowhere' is not HOST:PORT"),
        (["sim", "--faults", "drop=7"], "drop=7.0: expected a probability 0..1"),
        (["sim", "--quirks", "shouty"], "unknown quirk 'shouty'; known: lowercase_header"),
    ],
)
def test_bad_arguments_name_what_is_wrong(argv: list[str], message: str, capsys: pytest.CaptureFixture[str]) -> None:
    with pytest.raises(SystemExit) as exc:
        build_parser().parse_args(argv)
    assert exc.value.code == 2
    assert message in capsys.readouterr().err


def test_non_loopback_address_refused() -> None:
    from topgimbal.cli.main import main

    assert main(["sim", "--udp", "0.0.0.0:0"]) == 1
