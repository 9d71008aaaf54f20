"""The flake harness (`make flake RUNS=N HOG=H`): the loopback and external tiers N times, as `make
test` runs them (the parallel pass, then the serial one), optionally beside H busy loops, and a table
of what failed: test id, failures/runs; then each run's wall time, load and outcome.

A gate that is re-run until green proves nothing: this measures how often it is not, on this
machine, so a flake is found (and its root cause fixed) before it costs a good submission its
landing. The busy loops (`python3 -c 'while True: pass'`) stand for a noisy neighbour; they are
killed at the end, whatever happens.

Usage: python scripts/flake.py [--runs N] [--hog H] [--workers W] [--] [extra pytest arguments]
"""

from __future__ import annotations

import argparse
import os
import signal
import subprocess
import sys
import tempfile
import time
import xml.etree.ElementTree as ET
from collections import Counter
from dataclasses import dataclass, field
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
TIERS = "(loopback or external) and not service"
RUN_BOUND_S = 1800.0  # one run of both passes; a run that takes longer is killed and counted as such


@dataclass
class Run:
    number: int
    wall_s: float = 0.0
    load_before: float = 0.0
    load_after: float = 0.0
    codes: list[int] = field(default_factory=list)
    failed: list[str] = field(default_factory=list)
    counts: Counter[str] = field(default_factory=Counter)


def _failures(junit: Path) -> tuple[list[str], Counter[str]]:
    """Test ids that failed or errored, and the outcome counts, from a junit XML report."""
    failed: list[str] = []
    counts: Counter[str] = Counter()
    if not junit.exists():
        return ["(no report: the pass did not finish)"], counts
    for case in ET.parse(junit).getroot().iter("testcase"):
        module = case.get("classname", "").replace(".", "/")
        test_id = f"{module}.py::{case.get('name')}"
        outcome = "passed"
        for child in case:
            if child.tag in ("failure", "error"):
                outcome = "failed"
            elif child.tag == "skipped":
                outcome = "skipped"
        counts[outcome] += 1
        if outcome == "failed":
            failed.append(test_id)
    return failed, counts


def _pass(args: list[str], junit: Path, log: Path, bound_s: float) -> int:
    cmd = [sys.executable, "-m", "pytest", "-q", "-p", "no:cacheprovider", f"--junitxml={junit}", *args]
    with log.open("ab") as out:
        out.write(f"$ {' '.join(cmd)}\n".encode())
        out.flush()
        proc = subprocess.Popen(cmd, cwd=ROOT, stdout=out, stderr=subprocess.STDOUT, start_new_session=True)
        try:
            return proc.wait(bound_s)
        except subprocess.TimeoutExpired:
            return -1
        finally:
            try:
                os.killpg(proc.pid, signal.SIGKILL)
            except ProcessLookupError:
                pass
            proc.wait()


def one_run(number: int, workers: int, extra: list[str], logdir: Path) -> Run:
    run = Run(number, load_before=os.getloadavg()[0])
    start = time.monotonic()
    passes = [
        ["-n", str(workers), "--dist", "loadfile", "--max-worker-restart", "0", "-m", f"{TIERS} and not serial"],
        ["-m", f"{TIERS} and serial"],
    ]
    for i, args in enumerate(passes):
        junit = logdir / f"run{number}-pass{i}.xml"
        left_s = max(RUN_BOUND_S - (time.monotonic() - start), 60.0)
        run.codes.append(_pass([*args, *extra], junit, logdir / f"run{number}.log", left_s))
        failed, counts = _failures(junit)
        run.failed += failed
        run.counts += counts
    run.wall_s = time.monotonic() - start
    run.load_after = os.getloadavg()[0]
    return run


def start_hogs(n: int) -> list[subprocess.Popen[bytes]]:
    return [subprocess.Popen([sys.executable, "-c", "while True: pass"], start_new_session=True) for _ in range(n)]


def stop_hogs(hogs: list[subprocess.Popen[bytes]]) -> None:
    for hog in hogs:
        hog.kill()
        hog.wait()


def report(runs: list[Run], hog: int, logdir: Path) -> str:
    lines = [f"flake harness: {len(runs)} run(s) of the loopback and external tiers, {hog} busy loop(s) beside"]
    failures = Counter(test for run in runs for test in set(run.failed))
    width = max([len(t) for t in failures] + [len("test id")])
    lines.append(f"{'test id':<{width}}  failures/runs")
    for test, n in failures.most_common():
        lines.append(f"{test:<{width}}  {n}/{len(runs)}")
    if not failures:
        lines.append(f"{'(none)':<{width}}  0/{len(runs)}")
    lines.append("")
    lines.append("run  wall s  load 1-min before/after  exit codes  passed failed skipped")
    for run in runs:
        c = run.counts
        lines.append(
            f"{run.number:>3}  {run.wall_s:6.0f}  {run.load_before:10.1f} / {run.load_after:<10.1f}  "
            f"{','.join(map(str, run.codes)):<10}  {c['passed']:>6} {c['failed']:>6} {c['skipped']:>7}"
        )
    lines.append(f"logs and junit reports: {logdir}")
    return "\n".join(lines)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--runs", type=int, default=3)
    parser.add_argument("--hog", type=int, default=0, help="busy loops beside every run")
    parser.add_argument("--workers", type=int, default=int(os.environ.get("PYTEST_WORKERS", "6")))
    parser.add_argument("extra", nargs="*", help="more pytest arguments (after --)")
    args = parser.parse_args(argv)
    logdir = Path(tempfile.mkdtemp(prefix="flake-"))
    hogs = start_hogs(args.hog)
    runs: list[Run] = []
    try:
        for number in range(1, args.runs + 1):
            runs.append(one_run(number, args.workers, args.extra, logdir))
            print(f"run {number}: {runs[-1].wall_s:.0f} s, failed: {runs[-1].failed or 'none'}", flush=True)
            # the table so far, kept beside the logs: a harness stopped early still leaves one
            (logdir / "table.txt").write_text(report(runs, args.hog, logdir) + "\n", encoding="utf-8")
    finally:
        stop_hogs(hogs)
    print(report(runs, args.hog, logdir))
    return 1 if any(run.failed or any(runs_code not in (0, 5) for runs_code in run.codes) for run in runs) else 0


if __name__ == "__main__":
    sys.exit(main())
