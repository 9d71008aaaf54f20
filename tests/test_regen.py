"""Issue 28: one regeneration command for every file made from the catalog (tools/regen.py)."""

from __future__ import annotations

from pathlib import Path

from topgimbal.tools import regen

ROOT = Path(__file__).resolve().parents[1]


def test_every_generated_file_is_current() -> None:
    """What `make test` checks (`make docs-check`): a catalog change without `make docs` fails here."""
    assert regen.main(["--check"]) == 0


def test_a_stale_file_is_named_and_rewritten(tmp_path: Path, capsys) -> None:
    target = regen.Target("toy", "out", "tests.test_regen:_toy_files", "a toy directory")
    assert regen.stale((target,), tmp_path) == {Path("out/a.txt"): "A\n", Path("out/b.txt"): "B\n"}
    (tmp_path / "out").mkdir()
    (tmp_path / "out" / "a.txt").write_text("A\n")
    (tmp_path / "out" / "b.txt").write_text("old\n")
    assert list(regen.stale((target,), tmp_path)) == [Path("out/b.txt")]


def _toy_files() -> dict[str, str]:
    return {"a.txt": "A\n", "b.txt": "B\n"}


def test_check_fails_on_a_stale_file_and_the_rewrite_fixes_it(tmp_path: Path, capsys, monkeypatch) -> None:
    target = regen.Target("toy", "out", "tests.test_regen:_toy_files", "a toy directory")
    monkeypatch.setattr(regen, "REGISTRY", (target,))
    assert regen.main(["--check", "--root", str(tmp_path)]) == 1
    assert "out/a.txt is stale" in capsys.readouterr().err
    assert regen.main(["--root", str(tmp_path)]) == 0
    assert (tmp_path / "out" / "b.txt").read_text() == "B\n"
    assert regen.main(["--check", "--root", str(tmp_path)]) == 0
    assert regen.main(["nosuch", "--root", str(tmp_path)]) == 2


def test_every_target_is_marked_generated_for_linguist() -> None:
    lines = (ROOT / ".gitattributes").read_text().splitlines()
    marked = {line.split()[0] for line in lines if line.strip() and not line.startswith("#")}
    for target in regen.REGISTRY:
        is_dir = (ROOT / target.path).is_dir()
        assert (f"{target.path}/**" if is_dir else target.path) in marked, target.path


def test_make_docs_and_make_test_run_the_one_command() -> None:
    makefile = (ROOT / "Makefile").read_text()
    docs = makefile.split("\ndocs:", 1)[1].split("\n\n", 1)[0]
    check = makefile.split("\ndocs-check:", 1)[1].split("\n\n", 1)[0]
    assert "topgimbal.tools.regen" in docs and "topgimbal.tools.regen --check" in check
    test_line = next(line for line in makefile.splitlines() if line.startswith("test:"))
    assert "docs-check" in test_line.split()
