"""examples/c/point_camera points the simulated C12 over loopback UDP with libtopgimbal."""

from __future__ import annotations

import re
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
C = ROOT / "c"


@pytest.mark.integration
def test_example_points_the_simulated_camera(tmp_path: Path) -> None:
    exe = tmp_path / "point_camera"
    sources = [str(p) for p in sorted((C / "src").glob("*.c"))] + [str(C / "generated" / "tg_catalog.c")]
    subprocess.run(
        ["gcc", "-std=c99", "-O2", "-Wall", "-Wextra", "-Werror", "-I", str(C / "include"), "-I", str(C / "generated"),
         str(ROOT / "examples" / "c" / "point_camera.c"), *sources, "-o", str(exe)],
        check=True,
    )  # fmt: skip
    sim = subprocess.Popen(
        [sys.executable, "-m", "topgimbal.cli.main", "sim", "--model", "C12", "--udp", "127.0.0.1:0"],
        stdout=subprocess.PIPE,
        text=True,
    )
    try:
        port = None
        assert sim.stdout is not None
        for _ in range(5):
            m = re.search(r"udp://127\.0\.0\.1:(\d+)", sim.stdout.readline())
            if m:
                port = m.group(1)
                break
        assert port, "the simulator did not print its address"
        r = subprocess.run(
            [str(exe), "udp", "127.0.0.1", port, "12.5", "-7"], capture_output=True, text=True, timeout=30
        )
        assert r.returncode == 0, r.stderr
        m = re.search(r"reached yaw (-?[\d.]+) pitch (-?[\d.]+)", r.stdout)
        assert m and abs(float(m.group(1)) - 12.5) <= 0.5 and abs(float(m.group(2)) + 7) <= 0.5, r.stdout
    finally:
        sim.terminate()
        sim.wait(timeout=10)
