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

pytestmark = [pytest.mark.loopback, pytest.mark.integration]


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


@pytest.mark.parametrize("kind", ["udp", "tcp"])
def test_a_taken_port_is_named_with_the_way_out(kind: str, capsys: pytest.CaptureFixture[str]) -> None:
    from topgimbal.cli.main import main

    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM if kind == "udp" else socket.SOCK_STREAM) as s:
        s.bind((LOOP, 0))
        if kind == "tcp":
            s.listen()
        port = s.getsockname()[1]
        assert main(["sim", f"--{kind}", f"{LOOP}:{port}"]) == 1
    err = capsys.readouterr().err
    assert err == (
        f"topgimbal: error: cannot listen on {kind} {LOOP}:{port}: address already in use "
        f"(another program (or simulator) has it; use {LOOP}:0 for any free port)\n"
    )


def test_console_on_an_explicitly_taken_port_is_refused() -> None:
    """`--port N` is the user's choice: a taken N is a usage error (exit 2, one line), never a
    silent move to another port (issue 35.6); only the default port falls back (make demo)."""
    pytest.importorskip("aiohttp")
    with socket.socket(socket.AF_INET, socket.SOCK_STREAM) as s:
        s.bind((LOOP, 0))
        s.listen()
        taken = s.getsockname()[1]
        out = subprocess.run(
            [
                sys.executable,
                "-m",
                "topgimbal.cli.main",
                "console",
                "--sim",
                "C12",
                "--port",
                str(taken),
                "--seconds",
                "1",
            ],
            capture_output=True,
            text=True,
            timeout=60,
        )
    assert out.returncode == 2, out.stderr
    assert f"--port {taken} is taken" in out.stderr and "--port 0" in out.stderr
    assert "http://" not in out.stdout


@pytest.mark.parametrize(
    ("argv", "message"),
    [
        (["sim", "--udp-lease", "-1"], "'-1' is not seconds: expected a number >= 0 (0 = no lease)"),
        (["sim", "--udp-lease", "inf"], "'inf' is not seconds"),
        (["sim", "--max-udp-peers", "0"], "'0' is not a count: expected a whole number, 1 or more"),
        (["sim", "--max-tcp-clients", "x"], "'x' is not a count"),
        (["sim", "--tcp-buffer-kib", "-4"], "'-4' is not a count"),
    ],
)
def test_bad_limits_name_what_is_allowed(argv: list[str], message: str, capsys: pytest.CaptureFixture[str]) -> None:
    with pytest.raises(SystemExit):
        build_parser().parse_args(argv)
    assert message in capsys.readouterr().err


def test_limits_reach_the_simulator(monkeypatch: pytest.MonkeyPatch) -> None:
    from topgimbal.cli import sim_cmd

    seen = {}

    async def fake_serve(sim: object, listen: object, args: object = None) -> int:
        seen["limits"] = sim.limits  # type: ignore[attr-defined]
        return 0

    monkeypatch.setattr(sim_cmd, "_serve", fake_serve)
    args = build_parser().parse_args(
        ["sim", "--udp-lease", "0", "--max-udp-peers", "3", "--max-tcp-clients", "2", "--tcp-buffer-kib", "16"]
    )
    assert sim_cmd.run(args) == 0
    limits = seen["limits"]
    assert (limits.udp_lease_s, limits.max_udp_peers, limits.max_tcp_clients, limits.tcp_buffer_bytes) == (
        0.0,
        3,
        2,
        16384,
    )
