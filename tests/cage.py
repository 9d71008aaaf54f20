"""A cage for a test that drives a program able to hang its caller (tests/conftest.py loads the hooks).

A test marked `pytest.mark.cage(bound_s)` runs in a child pytest of its own, in a process group of its
own, killed hard (SIGKILL to the group: the child and whatever it started) after `bound_s`. A hang
then fails that one test, with every thread's stack (the child's faulthandler prints them shortly
before the kill) and the child's output, and never the rest of the run: before the cage, MAVSDK's
camera plugin blocked for good inside `mavsdk_camera_destroy` (a C call no timeout interrupts) and
took the whole serial pass with it, on 2 of 2 runs of a quiet machine.

In the child, the process ends with `os._exit` as soon as the test's outcome is known (its call, or
a setup that failed or skipped), before any teardown: library objects still alive are never torn
down in-process (MAVSDK's plugins destroy themselves in `__del__`, the call that hung; and with the
test's own objects gone, MAVSDK's threads called back into freed ones: a segfault in the fixtures'
teardown, seen). The kernel reclaims everything with the process group. The outcome goes to the
parent in a small JSON file, the child's output beside it.
"""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import tempfile
from pathlib import Path

import pytest

CHILD_ENV = "TOPGIMBAL_CAGED"  # set in the child: it runs the test itself
RESULT_ENV = "TOPGIMBAL_CAGE_RESULT"  # where the child writes its outcome
STACKS_BEFORE_KILL_S = 10.0  # the child's faulthandler prints every stack this long before the kill
TAIL_LINES = 200


class CageBoundError(AssertionError):
    """A caged test's child did not end within its bound: it was killed."""


def in_child() -> bool:
    return os.environ.get(CHILD_ENV) == "1"


def _bound_s(item: pytest.Item) -> float | None:
    mark = item.get_closest_marker("cage")
    if mark is None or in_child():
        return None
    return float(mark.args[0] if mark.args else mark.kwargs.get("bound_s", 300.0))


def _tail(text: str) -> str:
    lines = text.splitlines()
    return "\n".join(lines[-TAIL_LINES:])


def run_caged(item: pytest.Item, bound_s: float) -> None:
    """Run `item` in a child pytest; raise as the test would have (fail, skip), or CageBoundError."""
    with tempfile.TemporaryDirectory(prefix="cage-") as tmp:
        result = Path(tmp) / "result.json"
        env = dict(os.environ, **{CHILD_ENV: "1", RESULT_ENV: str(result)})
        for name in ("PYTEST_XDIST_WORKER", "PYTEST_XDIST_WORKER_COUNT", "PYTEST_XDIST_TESTRUNUID", "PYTEST_ADDOPTS"):
            env.pop(name, None)
        stacks_at_s = max(bound_s - STACKS_BEFORE_KILL_S, bound_s / 2)
        cmd = [sys.executable, "-m", "pytest", "-p", "no:cacheprovider", "-p", "no:xdist", "-q",
               "-o", f"faulthandler_timeout={stacks_at_s:.0f}", "-o", f"timeout={bound_s + 60:.0f}",
               item.nodeid]  # fmt: skip
        with open(Path(tmp) / "output.txt", "w+b") as out:
            proc = subprocess.Popen(
                cmd, cwd=item.config.rootpath, env=env, stdout=out, stderr=subprocess.STDOUT, start_new_session=True
            )
            try:
                code: int | None = proc.wait(bound_s)
            except subprocess.TimeoutExpired:
                code = None
            finally:
                try:  # the whole group: mavsdk's, ffmpeg's or Chromium's own children too
                    os.killpg(proc.pid, signal.SIGKILL)
                except ProcessLookupError:
                    pass
                proc.wait()
            out.seek(0)
            text = _tail(out.read().decode(errors="replace"))
        outcome = json.loads(result.read_text()) if result.exists() else None
    if code is None:
        raise CageBoundError(f"{item.nodeid}: still running after {bound_s:.0f} s, killed. Its output:\n{text}")
    if outcome is None:
        pytest.fail(
            f"{item.nodeid}: the caged child ended ({code}) with no outcome. Its output:\n{text}", pytrace=False
        )
    if outcome["outcome"] == "skipped":
        pytest.skip(f"(caged) {outcome['text']}")
    if outcome["outcome"] == "failed":
        pytest.fail(f"(caged, {outcome['when']}) {outcome['text']}\n--- the child's output ---\n{text}", pytrace=False)


@pytest.hookimpl(tryfirst=True)
def pytest_runtest_protocol(item: pytest.Item, nextitem: pytest.Item | None) -> bool | None:
    """The parent's side: no fixture of a caged test is set up here, the child sets up its own."""
    bound_s = _bound_s(item)
    if bound_s is None:
        return None
    from _pytest.runner import CallInfo

    hook = item.ihook
    hook.pytest_runtest_logstart(nodeid=item.nodeid, location=item.location)
    for when, run in (
        ("setup", lambda: None),
        ("call", lambda: run_caged(item, bound_s)),
        # the runner's own teardown step: the item before this one may have left collectors set up
        # (its module, its package) that the next item does not share; pytest refuses to go on then
        ("teardown", lambda: item.session._setupstate.teardown_exact(nextitem)),
    ):
        call = CallInfo.from_call(run, when=when)  # type: ignore[arg-type]
        report = hook.pytest_runtest_makereport(item=item, call=call)
        hook.pytest_runtest_logreport(report=report)
    hook.pytest_runtest_logfinish(nodeid=item.nodeid, location=item.location)
    return True


def pytest_runtest_logreport(report: pytest.TestReport) -> None:
    """The child's end: the outcome is known; leave without any teardown (the module's docstring)."""
    if not in_child() or not (report.when == "call" or report.failed or report.skipped):
        return
    text = report.longreprtext
    if report.skipped and isinstance(report.longrepr, tuple):
        text = str(report.longrepr[2])
    for title, content in report.sections:
        text += f"\n--- {title} ---\n{content}"
    outcome = {"outcome": report.outcome, "when": report.when, "text": text}
    Path(os.environ[RESULT_ENV]).write_text(json.dumps(outcome), encoding="utf-8")
    sys.stdout.flush()
    sys.stderr.flush()
    os._exit(0)
