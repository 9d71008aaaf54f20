"""kill -9 a real simulator process under a stream of acknowledged writes, N times: after every
restart the last acknowledged write is there (0 lost) and no temporary file is left.

Each round's simulator is `topgimbal sim --state FILE` run by the CLI's own `main()` in a process
forked from a helper that imported topgimbal once (a fresh interpreter per round would spend the
test's time budget on imports, not on kills)."""

from __future__ import annotations

import json
import os
import random
import signal
import socket
import subprocess
import sys
import time
from pathlib import Path

import pytest

from topgimbal.sim import persist

from .conftest import LOOP, frames, req

pytestmark = [pytest.mark.loopback, pytest.mark.integration]

ROUNDS = int(os.environ.get("TOPGIMBAL_KILL_ROUNDS", "50"))
WINDOW = 4  # writes in flight at once: the group commit gets batches to share

FORKER = r"""
import os, signal, sys
signal.signal(signal.SIGCHLD, signal.SIG_IGN)  # children are reaped by the kernel
from topgimbal.cli.main import main
for line in sys.stdin:
    pid = os.fork()
    if pid == 0:
        os._exit(main(line.split()))
    print(f"pid {pid}", flush=True)
"""


def address(i: int) -> str:
    return f"10.{(i >> 16) & 255}.{(i >> 8) & 255}.{i & 255}"


def counter(ip: str) -> int:
    """The write number an address carries (0: the factory address, no write yet)."""
    a, b, c, d = (int(x) for x in ip.split("."))
    return (b << 16) | (c << 8) | d if a == 10 else 0


class Forker:
    def __init__(self) -> None:
        self.proc = subprocess.Popen(
            [sys.executable, "-c", FORKER], stdin=subprocess.PIPE, stdout=subprocess.PIPE, text=True
        )

    def start_sim(self, state: Path) -> tuple[int, int]:
        assert self.proc.stdin is not None and self.proc.stdout is not None
        self.proc.stdin.write(f"sim --model C12 --udp {LOOP}:0 --state {state}\n")
        self.proc.stdin.flush()
        pid = port = None
        while pid is None or port is None:
            line = self.proc.stdout.readline()
            assert line, "the forker died"
            if line.startswith("pid "):
                pid = int(line.split()[1])
            elif line.startswith("udp://"):
                port = int(line.strip().rsplit(":", 1)[1])
        return pid, port

    def close(self) -> None:
        self.proc.kill()
        self.proc.wait(10)


def kill_and_wait(pid: int) -> None:
    os.kill(pid, signal.SIGKILL)
    for _ in range(1000):
        try:
            os.kill(pid, 0)
        except ProcessLookupError:
            return
        time.sleep(0.005)
    raise AssertionError(f"simulator {pid} survived kill -9")


def acked(data: bytes) -> list[int]:
    """The write numbers a datagram acknowledges."""
    return [counter(f.data.decode()) for f in frames(data) if f.ident == "IPV"]


def ask_ip(sock: socket.socket, port: int) -> str:
    for _ in range(5):
        sock.sendto(req("C12", "IPV", read=True), (LOOP, port))
        try:
            data = sock.recv(200)
        except TimeoutError:
            continue
        for f in frames(data):
            if f.ident == "IPV":
                return f.data.decode()
    raise AssertionError("no IPV answer")


def test_acknowledged_writes_survive_kill_9(tmp_path: Path) -> None:
    state = tmp_path / "cam.json"
    rng = random.Random(9)
    forker = Forker()
    last_acked, last_sent, lost, rounds = 0, 0, 0, 0
    try:
        for rnd in range(ROUNDS + 1):
            pid, port = forker.start_sim(state)
            with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as sock:
                sock.bind((LOOP, 0))
                sock.settimeout(5)
                # Restarted: the last acknowledged write is there, temporaries are gone.
                if rnd:
                    found = counter(ask_ip(sock, port))
                    lost += found < last_acked
                    assert last_acked <= found <= last_sent, (rnd, last_acked, found, last_sent)
                    last_acked = last_sent = found
                    assert [p.name for p in tmp_path.iterdir()] == ["cam.json"]
                if rnd == ROUNDS:
                    kill_and_wait(pid)
                    break
                # A stream of writes, WINDOW in flight; killed after a random number of acks.
                kill_after = rng.randint(1, 30)
                acks = 0
                while acks < kill_after:
                    while last_sent - last_acked < WINDOW:
                        last_sent += 1
                        sock.sendto(req("C12", "IPV", address=address(last_sent)), (LOOP, port))
                    got = acked(sock.recv(200))
                    last_acked = max([last_acked, *got])
                    acks += len(got)
                time.sleep(rng.random() * 0.003)
                kill_and_wait(pid)
                rounds += 1
                sock.setblocking(False)  # acknowledgements that left before the kill count too
                while True:
                    try:
                        last_acked = max([last_acked, *acked(sock.recv(200))])
                    except BlockingIOError:
                        break
    finally:
        forker.close()
    assert rounds == ROUNDS and lost == 0
    assert json.loads(state.read_text())["format"] == persist.FORMAT
