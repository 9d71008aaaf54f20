"""`topgimbal console` as a service manager or a script runs it: SIGTERM, and Ctrl-C even when the
console was started with SIGINT ignored (a background job), end it in order with exit status 0."""

from __future__ import annotations

import signal
import subprocess
import sys
import urllib.request

import pytest

pytestmark = [pytest.mark.loopback, pytest.mark.integration]


def _ignore_sigint() -> None:
    signal.signal(signal.SIGINT, signal.SIG_IGN)  # as `cmd &` in a script starts its jobs


@pytest.mark.parametrize("stop", [signal.SIGTERM, signal.SIGINT])
def test_the_console_stops_in_order_on_a_signal(stop: signal.Signals) -> None:
    proc = subprocess.Popen(
        [sys.executable, "-m", "topgimbal.cli.main", "console", "--sim", "C12", "--host", "127.0.0.1", "--port", "0"],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
        preexec_fn=_ignore_sigint,
    )
    try:
        assert proc.stdout is not None
        url = next(line.split()[-1] for line in proc.stdout if "http://127.0.0.1:" in line)
        with urllib.request.urlopen(url.split("?")[0] + "api/catalog", timeout=10) as reply:
            assert reply.status == 200  # serving
        proc.send_signal(stop)
        assert proc.wait(20) == 0
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.wait()
    assert proc.stderr is not None
    assert "Traceback" not in proc.stderr.read()
