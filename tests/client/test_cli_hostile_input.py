"""The CLI given what a careless or hostile user gives it: NaN, infinity and negative numbers, FIFOs,
files that are not what the command reads, output paths that cannot be written, a device that does
not answer, Ctrl-C. Each gets one clear line and the right exit status (2: usage, 1: failure,
130: interrupted), never a traceback, a hang, or a success that did nothing."""

from __future__ import annotations

import contextlib
import os
import signal
import subprocess
import sys
from collections.abc import Callable
from pathlib import Path

import pytest

from topgimbal.cli.main import main
from topgimbal.sim import BackgroundSimulator, FaultPlan

pytestmark = [pytest.mark.loopback, pytest.mark.integration]

NOWHERE = ["--url", "udp://127.0.0.1:9", "--model", "C12"]  # parsing fails before anything is sent


@pytest.fixture(scope="module")
def sim():
    with BackgroundSimulator("C12", seed=3, listen={"udp": [("127.0.0.1", 0)]}) as bg:
        yield ["--url", dict(bg.endpoints)["udp"], "--model", "C12"]


@pytest.fixture(scope="module")
def silent():
    """A camera that never answers (every datagram dropped)."""
    faults = FaultPlan.parse("drop=1.0")
    with BackgroundSimulator("C12", seed=3, listen={"udp": [("127.0.0.1", 0)]}, faults=faults) as bg:
        yield ["--url", dict(bg.endpoints)["udp"], "--model", "C12"]


def run(capsys, *argv: str) -> tuple[int, str, str]:
    try:
        code = main(list(argv))
    except SystemExit as exc:  # argparse's usage errors
        code = int(exc.code or 0)
    out, err = capsys.readouterr()
    return code, out, err


def cli(*argv: str, timeout_s: float = 60) -> subprocess.CompletedProcess[str]:
    """In a child process: an input that hangs the command fails the test instead of hanging it."""
    return subprocess.run(
        [sys.executable, "-m", "topgimbal.cli.main", *argv],
        capture_output=True,
        text=True,
        timeout=timeout_s,
        stdin=subprocess.DEVNULL,
    )


# -- numbers ---------------------------------------------------------------------------------------


@pytest.mark.parametrize(
    ("argv", "option"),
    [
        (["rate", "5", "--duration", "nan"], "--duration"),  # was: "ok, stopped" after no time at all
        (["rate", "5", "--duration", "-1"], "--duration"),
        (["rate", "5", "--duration", "inf"], "--duration"),  # was: turned until killed
        (["rate", "nan"], "YAW_RATE"),
        (["attitude", "--watch", "--count", "-1"], "--count"),  # was: one sample, exit 0
        (["attitude", "--watch", "--rate", "0"], "--rate"),
        (["monitor", "--fps", "0", "--json"], "--fps"),  # was: a 10 s wait per frame
        (["monitor", "--fps", "nan", "--json"], "--fps"),
        (["monitor", "--count", "-1", "--json"], "--count"),  # was: nothing printed, exit 0
        (["log", "x.jsonl", "--seconds", "nan"], "--seconds"),  # was: an empty log, exit 0
        (["log", "x.jsonl", "--seconds", "-1"], "--seconds"),
        (["log", "x.jsonl", "--stream", "inf"], "--stream"),
        (["replay", "x.jsonl", "--speed", "0"], "--speed"),
    ],
)
def test_a_bad_number_is_a_usage_error_naming_the_option(capsys, tmp_path, monkeypatch, argv, option):
    monkeypatch.chdir(tmp_path)
    code, _, err = run(capsys, *NOWHERE, *argv, "--timeout", "0.2", "--retries", "0")
    assert code == 2, err
    assert f"argument {option}:" in err and "expected" in err
    assert not (tmp_path / "x.jsonl").exists()


@pytest.mark.parametrize("value", ["nan", "inf", "-1", "0", "1e9"])
def test_sim_refuses_a_stream_rate_that_would_stop_or_spin_the_stream(capsys, value):
    # was: nan and -1 served a stream that never came (a client waited for ever), 1e9 spun the loop
    code, _, err = run(capsys, "sim", "--model", "SIP", "--udp", "127.0.0.1:0", f"--stream-hz={value}")
    assert code == 2 and "argument --stream-hz:" in err and "up to 1000" in err


@pytest.mark.parametrize("value", ["inf", "nan"])
def test_zoom_to_a_non_finite_magnification_is_a_clear_error(sim, capsys, value):
    # was: OverflowError traceback (inf), "cannot convert float NaN to integer" (nan)
    code, _, err = run(capsys, *sim, "zoom", value)
    assert code == 2 and "zoom=" in err and "in, out, stop or a magnification" in err


@pytest.mark.parametrize(
    ("argv", "shown"),
    [
        (["rate", "20"], "YAW_RATE=20.0"),  # was: yaw_rate_deg_s=-20.0 (the C12's wire sign)
        (["rate", "0", "--", "-20"], "PITCH_RATE=-20.0"),
        (["rate", "0", "--roll-rate", "99"], "--roll-rate=99.0"),
    ],
)
def test_a_rate_out_of_range_is_reported_as_typed(sim, capsys, argv, shown):
    code, _, err = run(capsys, *sim, *argv)
    assert code == 2 and shown in err and "-12.7..12.7" in err


# -- input files -----------------------------------------------------------------------------------


@pytest.fixture
def fifo(tmp_path: Path) -> Path:
    path = tmp_path / "fifo"
    os.mkfifo(path)
    return path


@pytest.mark.parametrize(
    "argv",
    [
        ["replay", "{fifo}", "--fast"],
        ["pcap", "from-log", "{fifo}", "-o", "{tmp}/out.pcap"],
        ["decode", "--pcap", "{fifo}"],
        ["dissector", "--check", "{fifo}"],
    ],
)
def test_a_fifo_is_refused_not_waited_on(sim, fifo, tmp_path, argv):
    # was: each blocked for ever in open() (a FIFO with no writer)
    proc = cli(*sim, *[a.format(fifo=fifo, tmp=tmp_path) for a in argv])
    assert proc.returncode == 1 and "is a FIFO: give a regular file" in proc.stderr
    assert "Traceback" not in proc.stderr
    assert not (tmp_path / "out.pcap").exists()


@pytest.mark.parametrize(
    ("content", "said"),
    [
        (b"5\n[1]\n", "is not a traffic log: a line is not a record"),  # was: TypeError traceback
        (b'{"dir": "out", "raw": 5}\n', "is not a traffic log"),  # was: AttributeError traceback
        (b"\xff\xfe garbage\n", "is not a traffic log: not UTF-8 text"),
        (b"", "holds no host -> device frames"),  # was: "sent: 0", exit 0
        (b'{"a": 1}\n' + b"x" * 100_000 + b"\n", "holds no host -> device frames"),
    ],
)
def test_replay_of_a_file_that_is_not_a_log_says_so(sim, capsys, tmp_path, content, said):
    path = tmp_path / "bad.jsonl"
    path.write_bytes(content)
    code, _, err = run(capsys, *sim, "replay", str(path), "--fast")
    assert code == 1 and f"{path} {said}" in err


def test_dissector_check_of_a_binary_file_calls_it_stale(capsys, tmp_path):
    path = tmp_path / "junk.lua"
    path.write_bytes(b"\xe3\x01\xff")  # was: "'utf-8' codec can't decode byte", without the file
    code, _, err = run(capsys, "dissector", "--check", str(path))
    assert code == 1 and f"{path} is stale" in err


# -- output files ----------------------------------------------------------------------------------


def test_log_checks_its_pcap_path_before_recording(sim, capsys, tmp_path):
    log = tmp_path / "s.jsonl"
    code, _, err = run(capsys, *sim, "log", str(log), "--seconds", "0.2", "--pcap", str(tmp_path / "no" / "s.pcap"))
    assert code == 1 and "the directory" in err and "does not exist" in err
    assert not log.exists()  # was: recorded for --seconds, then failed, leaving the log behind unmentioned


@pytest.mark.parametrize(
    "argv",
    [["dissector", "-o", "{out}"], ["pcap", "from-log", "{log}", "-o", "{out}"]],
)
def test_an_output_in_a_missing_directory_is_named(capsys, tmp_path, argv):
    log = tmp_path / "t.jsonl"
    log.write_text('{"dir": "out", "raw": "#TPUD2rVER0051", "t": 1.0, "mono": 1.0}\n')
    out = tmp_path / "missing" / "o.out"
    code, _, err = run(capsys, *[a.format(out=out, log=log) for a in argv])
    assert code == 1 and f"{out}: the directory {out.parent} does not exist" in err


def test_dissector_output_is_replaced_whole(capsys, tmp_path):
    out = tmp_path / "d.lua"
    out.write_text("old")
    assert run(capsys, "dissector", "-o", str(out))[0] == 0
    assert run(capsys, "dissector", "--check", str(out))[0] == 0
    assert [p.name for p in tmp_path.iterdir()] == ["d.lua"]  # no temporary file left behind


def test_sim_refuses_a_state_file_it_could_never_write():
    # was: served, and failed at the first setting change (a reply it could not honour)
    proc = cli("sim", "--udp", "127.0.0.1:0", "--state", "/nonexistent-dir/state.json", timeout_s=30)
    assert proc.returncode == 1 and "state file" in proc.stderr and "does not exist" in proc.stderr


def test_a_log_that_fails_keeps_and_names_what_it_recorded(silent, capsys, tmp_path):
    log, pcap = tmp_path / "s.jsonl", tmp_path / "s.pcap"
    code, _, err = run(capsys, *silent, "log", str(log), "--seconds", "0.5", "--stream", "10", "--pcap", str(pcap))
    assert code == 1
    line = err.strip().splitlines()[-1]
    assert f"{log} keeps the" in line and "before the error" in line and f"{pcap} their capture" in line
    assert log.stat().st_size > 0 and pcap.stat().st_size > 0


# -- Ctrl-C ----------------------------------------------------------------------------------------


def _interrupt_when(argv: list[str], ready: Callable[[subprocess.Popen[str]], None]) -> tuple[int, str]:
    """Run the CLI, send SIGINT once `ready(proc)` returns, give its exit status and stderr."""
    proc = subprocess.Popen(
        [sys.executable, "-m", "topgimbal.cli.main", *argv],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        stdin=subprocess.DEVNULL,
        text=True,
        # Ctrl-C as a terminal delivers it: a CI script run in the background (`&`, nohup) has
        # SIGINT ignored, and the CLI would inherit that.
        preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_DFL),
    )
    try:
        ready(proc)
        proc.send_signal(signal.SIGINT)
        code = proc.wait(30)
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.wait()
    assert proc.stderr is not None
    return code, proc.stderr.read()


def test_ctrl_c_says_interrupted(sim):
    def first_sample(proc: subprocess.Popen[str]) -> None:
        assert proc.stdout is not None and proc.stdout.readline()  # blocking on the device now

    code, err = _interrupt_when([*sim, "attitude", "--watch", "--rate", "5"], first_sample)
    assert code == 130 and "topgimbal: interrupted" in err and "Traceback" not in err  # was: silent


def test_ctrl_c_during_log_still_writes_the_capture(sim, tmp_path):
    log, pcap = tmp_path / "s.jsonl", tmp_path / "s.pcap"

    def streaming(proc: subprocess.Popen[str]) -> None:
        for _ in range(600):  # until the device's stream is in the log (bounded: 60 s)
            if log.exists() and log.read_text().count('"dir": "in"') >= 3:
                return
            with contextlib.suppress(subprocess.TimeoutExpired):
                proc.wait(0.1)

    argv = [*sim, "log", str(log), "--seconds", "600", "--stream", "10", "--pcap", str(pcap)]
    code, err = _interrupt_when(argv, streaming)
    assert code == 130 and "log interrupted" in err and f"{pcap} their capture" in err, err
    assert pcap.stat().st_size > 24  # more than the pcap header: the frames recorded (was: no file)
