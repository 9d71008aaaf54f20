"""How fast the CLI starts (issue 28): `topgimbal --help` and a one-frame `decode`.

Each command runs --runs times as a fresh process; printed: the median wall time, the median CPU
time of the child (user + system, which a busy shared machine disturbs far less than the wall
time), the number of modules it imported (all / topgimbal's) and the ten slowest imports from
`python -X importtime`. Modules load from cached bytecode, as in any install: the bench unsets
PYTHONDONTWRITEBYTECODE, points PYTHONPYCACHEPREFIX at a temporary directory (the work tree stays
clean) and runs each case once before timing it. `--no-bytecode` times compiling every module from
source on every start instead (what an environment with PYTHONDONTWRITEBYTECODE=1 pays). Python's own start (`python -c pass`) is printed as the floor. `--src DIR`
runs another checkout's `src` (a before/after comparison in one run: `git archive BASE src | tar -x
-C /tmp/base`, copy the built `src/topgimbal/_speedups/_ctop*.so` next to its `_ctop.c` (git archive
leaves it out, and without it the base runs the pure path), then `--src /tmp/base/src`).

    .venv/bin/python bench/cli_start.py [--runs 5] [--src DIR]
"""

from __future__ import annotations

import argparse
import os
import resource
import statistics
import subprocess
import sys
import tempfile
import time

FRAME = "#TPUG6wGAYEC78324D"  # SkyDroid's: its dialect alone decodes it (decode_any builds one dialect)
TOPOTEK_FRAME = "#TPUG2rGIA0038"  # TOPOTEK's: ranking it needs both dialects
CASES = {
    "python -c pass": ["-c", "pass"],
    "topgimbal --help": ["-m", "topgimbal.cli.main", "--help"],
    "topgimbal decode FRAME": ["-m", "topgimbal.cli.main", "decode", FRAME],
    "decode TOPOTEK_FRAME": ["-m", "topgimbal.cli.main", "decode", TOPOTEK_FRAME],
}
COUNT = (
    "import sys, runpy; sys.argv = {argv!r}\n"
    "try:\n    runpy.run_module('topgimbal.cli.main', run_name='__main__')\n"
    "except SystemExit:\n    pass\n"
    "print(len(sys.modules), sum(m.split('.')[0] == 'topgimbal' for m in sys.modules), file=sys.stderr)\n"
)


def _run(cmd: list[str], env: dict[str, str]) -> tuple[float, float]:
    """Wall and CPU seconds of one run of `cmd` as a child process."""
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    t0 = time.perf_counter()
    subprocess.run(cmd, env=env, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL, check=False)
    wall = time.perf_counter() - t0
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    return wall, (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime)


def _modules(argv: list[str], env: dict[str, str]) -> str:
    out = subprocess.run(
        [sys.executable, "-c", COUNT.format(argv=["topgimbal", *argv])],
        env=env,
        capture_output=True,
        text=True,
        check=False,
    )
    return out.stderr.strip().splitlines()[-1] if out.stderr.strip() else "?"


def _slowest(args: list[str], env: dict[str, str], n: int = 10) -> list[str]:
    out = subprocess.run(
        [sys.executable, "-X", "importtime", *args], env=env, capture_output=True, text=True, check=False
    )
    rows = []
    for line in out.stderr.splitlines():
        if not line.startswith("import time:") or "cumulative" in line:
            continue
        _self_us, cum_us, name = line.split(":", 1)[1].split("|")
        rows.append((int(cum_us), name.rstrip()))
    rows.sort(reverse=True)
    return [f"{cum / 1000:7.1f} ms cumulative  {name}" for cum, name in rows[:n]]


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--runs", type=int, default=5)
    ap.add_argument("--src", help="run this source tree instead of the installed topgimbal")
    ap.add_argument("--importtime", action="store_true", help="also print the slowest imports")
    ap.add_argument("--no-bytecode", action="store_true", help="compile every module on every start")
    a = ap.parse_args()
    env = dict(os.environ)
    cache = tempfile.TemporaryDirectory(prefix="cli_start_pycache.")
    if a.no_bytecode:
        env["PYTHONDONTWRITEBYTECODE"] = "1"
    else:
        env.pop("PYTHONDONTWRITEBYTECODE", None)
        env["PYTHONPYCACHEPREFIX"] = cache.name
    if a.src:
        env["PYTHONPATH"] = os.path.abspath(a.src)
    print("bytecode: " + ("compiled on every start" if a.no_bytecode else "cached (as installed)"))
    print(f"{'case':<26} {'wall median':>12} {'cpu median':>11}  modules (all / topgimbal)")
    for label, args in CASES.items():
        _run([sys.executable, *args], env)  # warms the bytecode cache
        runs = [_run([sys.executable, *args], env) for _ in range(a.runs)]
        wall = statistics.median(r[0] for r in runs)
        cpu = statistics.median(r[1] for r in runs)
        mods = _modules(args[2:], env) if args[0] == "-m" else "-"
        print(f"{label:<26} {wall:11.3f}s {cpu:10.3f}s  {mods}")
        if a.importtime and args[0] == "-m":
            for row in _slowest(args, env):
                print("    " + row)
    cache.cleanup()


if __name__ == "__main__":
    main()
