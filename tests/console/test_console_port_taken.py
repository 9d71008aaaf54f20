"""`console --port N` with N taken is an error (exit 2, one line), not a silent move to another port
(issue 35.6); without --port the default one still falls back to a free port and says so."""

from __future__ import annotations

import socket

import pytest

from topgimbal.cli.main import main

pytestmark = pytest.mark.loopback


def test_an_explicit_port_that_is_taken_is_refused(capsys) -> None:
    with socket.socket(socket.AF_INET, socket.SOCK_STREAM) as busy:
        busy.bind(("127.0.0.1", 0))
        busy.listen()
        port = busy.getsockname()[1]
        code = main(["console", "--sim", "C12", "--port", str(port), "--seconds", "0.5"])
    out, err = capsys.readouterr()
    assert code == 2 and out == "", (code, out, err)
    assert len(err.splitlines()) == 1 and f"--port {port} is taken" in err and "--port 0" in err
