"""`make demo` (python -m topgimbal.tools.demo) and `topgimbal console --sim`: start, print the
URL, serve the page, exit by themselves after --seconds."""

from __future__ import annotations

import json
import re
import subprocess
import sys
import time
import urllib.request

import pytest

pytestmark = [pytest.mark.loopback, pytest.mark.integration]

# How long the demo serves before it exits by itself: long enough that, on a loaded machine, the
# test still fetches the page within it (3 s was not, once, with six workers on two cores).
SERVE_S = 12


def _run_and_fetch(cmd: list[str], seconds: float) -> tuple[str, dict[str, object], int]:
    proc = subprocess.Popen(cmd, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
    try:
        assert proc.stdout is not None
        out = ""
        url = None
        # a bound on a hang, not on the start: a loaded machine took over 20 s to print the first two lines
        deadline = time.monotonic() + 120
        while url is None and time.monotonic() < deadline:
            line = proc.stdout.readline()
            if not line:
                break
            out += line
            m = re.search(r"(http://127\.0\.0\.1:\d+/\S*)", line)
            if m:
                url = m.group(1)
        assert url, f"no URL printed: {out!r}"
        with urllib.request.urlopen(url.split("?")[0] + "api/catalog", timeout=30) as r:
            catalog = json.load(r)
        with urllib.request.urlopen(url, timeout=30) as r:
            assert b'data-testid="btn-photo"' in r.read()
        rest, _ = proc.communicate(timeout=seconds + 20)
        return out + rest, catalog, proc.returncode
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.wait()


def test_demo_prints_url_serves_and_exits() -> None:
    out, catalog, code = _run_and_fetch(
        [sys.executable, "-m", "topgimbal.tools.demo", "--port", "0", "--seconds", str(SERVE_S)], SERVE_S
    )
    assert code == 0, out
    assert "simulated C12" in out
    assert catalog["model"]["name"] == "C12"  # type: ignore[index]


def test_console_command_with_sim() -> None:
    cmd = [
        sys.executable,
        "-m",
        "topgimbal.cli.main",
        "console",
        "--sim",
        "SIP",
        "--port",
        "0",
        "--seconds",
        str(SERVE_S),
    ]
    out, catalog, code = _run_and_fetch(cmd, SERVE_S)
    assert code == 0, out
    assert catalog["model"]["name"] == "SIP"  # type: ignore[index]
    assert "open http://127.0.0.1:" in out


def test_demo_falls_back_to_a_free_port() -> None:
    import socket

    from topgimbal.tools.demo import port_free

    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        s.listen()
        taken = s.getsockname()[1]
        assert not port_free(taken)
        out, _, code = _run_and_fetch(
            [sys.executable, "-m", "topgimbal.tools.demo", "--port", str(taken), "--seconds", str(SERVE_S)], SERVE_S
        )
    assert code == 0, out
    assert f"port {taken} is taken" in out
