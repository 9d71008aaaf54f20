"""examples/c/point_camera points the simulated C12 over loopback UDP with libtopgimbal."""

from __future__ import annotations

import re
import socket
import subprocess
import sys
from pathlib import Path

import pytest

pytestmark = pytest.mark.external

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


@pytest.fixture(scope="module")
def sanitized_example(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """The example built with ASan + UBSan (a NaN or huge angle cast to int64_t is caught)."""
    exe = tmp_path_factory.mktemp("example") / "point_camera"
    sources = [str(p) for p in sorted((C / "src").glob("*.c"))] + [str(C / "generated" / "tg_catalog.c")]
    subprocess.run(
        ["clang", "-std=c99", "-O1", "-g", "-Wall", "-Wextra", "-Wpedantic", "-Werror",
         "-fsanitize=address,undefined", "-fno-sanitize-recover=all", "-I", str(C / "include"),
         "-I", str(C / "generated"), str(ROOT / "examples" / "c" / "point_camera.c"), *sources, "-o", str(exe)],
        check=True,
    )  # fmt: skip
    return exe


BAD_ARGS = [
    ([], "usage:"),
    (["tcp", "127.0.0.1", "{port}", "1", "2"], "usage:"),
    (["udp", "127.0.0.1", "{port}", "abc", "2"], "bad yaw 'abc': expected degrees -"),
    (["udp", "127.0.0.1", "{port}", "1", "nan"], "bad pitch 'nan': expected degrees"),
    (["udp", "127.0.0.1", "{port}", "inf", "2"], "bad yaw 'inf'"),
    (["udp", "127.0.0.1", "{port}", "1e300", "2"], "bad yaw '1e300'"),
    (["udp", "127.0.0.1", "{port}", "500", "2"], "bad yaw '500'"),
    (["udp", "127.0.0.1", "{port}", "12.5x", "2"], "bad yaw '12.5x'"),
    (["udp", "127.0.0.1", "port", "1", "2"], "bad port 'port': expected a whole number 1..65535"),
    (["udp", "127.0.0.1", "70000", "1", "2"], "bad port '70000'"),
    (["udp", "localhost", "{port}", "1", "2"], "bad host 'localhost': expected a dotted IPv4 address"),
    (["serial", "/nonexistent/ttyTG0", "115200", "1", "2"], "cannot open serial device /nonexistent/ttyTG0"),
    (["serial", "/dev/null", "115200", "1", "2"], "cannot open serial device /dev/null"),
    (["serial", "/dev/null", "1234", "1", "2"], "bad baud rate '1234': expected 9600, 57600 or 115200"),
]


@pytest.mark.parametrize(("args", "message"), BAD_ARGS, ids=[" ".join(a) or "none" for a, _ in BAD_ARGS])
def test_example_refuses_bad_arguments_before_sending(sanitized_example: Path, args: list[str], message: str) -> None:
    """A non-numeric angle used to be read as 0 (the camera pointed at 0, 0), NaN cast to int64_t
    (undefined), an unknown transport opened its host as a serial device, and a bad port became 0;
    now each is a message naming the argument and what is allowed, exit 2, and nothing is sent."""
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as camera:
        camera.bind(("127.0.0.1", 0))
        camera.setblocking(False)
        port = str(camera.getsockname()[1])
        r = subprocess.run(
            [str(sanitized_example), *(a.replace("{port}", port) for a in args)],
            capture_output=True,
            text=True,
            timeout=30,
        )
        assert r.returncode == 2, (r.returncode, r.stderr)
        assert message in r.stderr and "runtime error" not in r.stderr, r.stderr
        with pytest.raises(BlockingIOError):
            camera.recv(512)


@pytest.mark.integration
def test_example_reports_the_cameras_refusal_at_once(sanitized_example: Path) -> None:
    """Pitch -60 on a C12 (range -45..45): the camera answers GAM with its error frame. The example
    used to ignore it and poll GAC for 15 s, then print the same timeout as for a silent camera;
    now it says the camera refused the angles, exit 3 (under ASan + UBSan)."""
    from topgimbal.sim import BackgroundSimulator

    with BackgroundSimulator("C12", seed=26, listen={"udp": [("127.0.0.1", 0)]}) as bg:
        host, port = bg.url.split("//", 1)[1].rsplit(":", 1)
        r = subprocess.run(
            [str(sanitized_example), "udp", host, port, "10", "-60"], capture_output=True, text=True, timeout=60
        )
        assert r.returncode == 3, (r.returncode, r.stdout, r.stderr)
        assert "refused the angles" in r.stderr and "timeout" not in r.stderr and "runtime error" not in r.stderr
        assert bg.call(lambda s: abs(s.gimbal.axis("pitch").target) < 1.0)  # nothing moved toward -60
        r = subprocess.run(
            [str(sanitized_example), "udp", host, port, "10", "-5"], capture_output=True, text=True, timeout=60
        )
        assert r.returncode == 0, (r.stdout, r.stderr)
        # the example stops within its 0.5 deg tolerance, wherever the moving gimbal was then
        reached = re.search(r"reached yaw (-?[\d.]+) pitch (-?[\d.]+)", r.stdout)
        assert reached is not None, r.stdout
        assert abs(float(reached[1]) - 10) <= 0.5 and abs(float(reached[2]) + 5) <= 0.5, r.stdout
