"""libtopgimbal checked from pytest: warning-free under gcc and clang, the vector runner (built
with each compiler) agrees with every vector the Python side produces, and the streaming parser
agrees with the Python parser on random streams (differential fuzzing through ctypes)."""

from __future__ import annotations

import importlib.util
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

from topgimbal.tools import cgen

pytestmark = pytest.mark.external

ROOT = Path(__file__).resolve().parents[2]
C = ROOT / "c"
STD = ["-std=c99", "-Wall", "-Wextra", "-Wpedantic", "-Werror", "-Wshadow", "-Wcast-qual", "-Wstrict-prototypes"]
INC = ["-I", str(C / "include"), "-I", str(C / "generated")]
LIB = [*sorted(str(p) for p in (C / "src").glob("*.c")), str(C / "generated" / "tg_catalog.c")]
COMPILERS = ["gcc", "clang"]


def _cc(cc: str) -> str:
    path = shutil.which(cc)
    assert path, f"{cc} is not installed: `make -C c deps` installs it"
    return path


@pytest.fixture(scope="module")
def vectors(tmp_path_factory: pytest.TempPathFactory) -> Path:
    path = tmp_path_factory.mktemp("vectors") / "vectors.txt"
    assert cgen.main(["--vectors", str(path)]) == 0
    return path


@pytest.mark.parametrize("cc", COMPILERS)
def test_library_is_warning_free(cc: str) -> None:
    for opt in ("-O0", "-O2", "-Os"):
        r = subprocess.run([_cc(cc), *STD, opt, *INC, "-fsyntax-only", *LIB], capture_output=True, text=True)
        assert r.returncode == 0, r.stderr


@pytest.mark.parametrize("cc", COMPILERS)
def test_vector_runner_passes(cc: str, vectors: Path, tmp_path: Path) -> None:
    exe = tmp_path / f"run_vectors-{cc}"
    build = [_cc(cc), *STD, "-O1", *INC, str(C / "tests" / "run_vectors.c"), *LIB, "-o", str(exe)]
    subprocess.run(build, check=True)
    r = subprocess.run([str(exe), str(vectors)], capture_output=True, text=True)
    last = r.stdout.strip().splitlines()[-1]
    passed = int(last.split()[0])
    assert last == f"{passed} passed, 0 failed" and r.returncode == 0, r.stderr
    assert passed > 5000  # every form, decode + encode + streams


def test_vector_runner_reports_failures(vectors: Path, tmp_path: Path) -> None:
    """A wrong vector is counted and makes the runner exit non-zero."""
    exe = tmp_path / "run_vectors"
    subprocess.run(
        [_cc("gcc"), *STD, "-O1", *INC, str(C / "tests" / "run_vectors.c"), *LIB, "-o", str(exe)], check=True
    )
    text = vectors.read_text()
    line = next(x for x in text.splitlines() if x.startswith("M ") and " n:" in x)
    token = next(t for t in line.split() if t.startswith("n:"))
    m, e = token[2:].split("e")
    bad = vectors.parent / "bad.txt"
    bad.write_text(text.replace(line, line.replace(token, f"n:{int(m) + 1}e{e}", 1), 1))
    r = subprocess.run([str(exe), str(bad)], capture_output=True, text=True)
    assert r.returncode == 1 and r.stdout.strip().endswith("passed, 1 failed"), r.stdout


def test_streaming_parser_agrees_with_python_parser(tmp_path: Path) -> None:
    lib = tmp_path / "shim.so"
    subprocess.run(
        [
            _cc("gcc"),
            "-std=c99",
            "-O2",
            "-fPIC",
            "-shared",
            *INC,
            str(C / "fuzz" / "diff_shim.c"),
            *LIB,
            "-o",
            str(lib),
        ],
        check=True,
    )
    spec = importlib.util.spec_from_file_location("diff_fuzz", C / "fuzz" / "diff_fuzz.py")
    assert spec and spec.loader
    mod = importlib.util.module_from_spec(spec)
    sys.modules["diff_fuzz"] = mod
    spec.loader.exec_module(mod)
    assert mod.run(str(lib), seconds=0, seed=12345, iterations=400) == 0


def test_fuzz_regression_inputs_pass(tmp_path: Path) -> None:
    """Inputs that once made the libFuzzer harness abort (c/fuzz/regressions/) run clean under ASan
    and UBSan: the parser delivers only frames tg_frame_write can write again."""
    inputs = sorted((C / "fuzz" / "regressions").iterdir())
    assert len(inputs) >= 3
    exe = tmp_path / "fuzz_parser"
    build = [_cc("clang"), "-g", "-O1", "-fsanitize=fuzzer,address,undefined", "-fno-sanitize-recover=all", *INC]
    subprocess.run([*build, str(C / "fuzz" / "fuzz_parser.c"), *LIB, "-o", str(exe)], check=True)
    r = subprocess.run([str(exe), *map(str, inputs)], capture_output=True, text=True, cwd=tmp_path, timeout=120)
    assert r.returncode == 0, r.stderr[-3000:]
    assert r.stderr.count("Executed") == len(inputs)
    assert not list(tmp_path.glob("crash-*"))


def test_no_fuzzer_artifacts_in_the_tree() -> None:
    """libFuzzer writes its crash inputs under c/build/ (-artifact_prefix), never next to the sources."""
    stray = [p for p in C.rglob("*") if p.name.startswith(("crash-", "leak-", "timeout-", "oom-"))]
    assert not [p for p in stray if (C / "build") not in p.parents]
    assert "-artifact_prefix=$(B)/artifacts/" in (C / "Makefile").read_text()


@pytest.mark.parametrize("cc", COMPILERS)
def test_api_misuse_is_caught_cleanly(cc: str, tmp_path: Path) -> None:
    """c/tests/api_misuse.c under ASan + UBSan: short output buffers, hostile values of every type,
    data of every length, NULL with length 0, parser resets mid-frame. A zero-length chunk at NULL
    used to pass NULL to memcpy (UBSan: "null pointer passed as argument 2"), and a form decoded
    without data applied an offset to NULL."""
    exe = tmp_path / f"api_misuse-{cc}"
    sanitize = ["-O1", "-g", "-fsanitize=address,undefined", "-fno-sanitize-recover=all"]
    subprocess.run(
        [_cc(cc), *STD, *sanitize, *INC, str(C / "tests" / "api_misuse.c"), *LIB, "-o", str(exe)], check=True
    )
    r = subprocess.run([str(exe)], capture_output=True, text=True, timeout=300)
    assert r.returncode == 0 and "runtime error" not in r.stderr, r.stderr[-3000:]
    checks, failed = (int(w) for w in r.stdout.split()[::2][:2])
    assert failed == 0 and checks > 100_000, r.stdout
