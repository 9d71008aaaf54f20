"""docs/architecture.md's recipes name test files, tests and source files to copy or edit: each
must exist, so a rename cannot leave a recipe pointing at nothing."""

from __future__ import annotations

import ast
import re
from pathlib import Path

import pytest

pytestmark = pytest.mark.virtual

ROOT = Path(__file__).resolve().parents[2]
DOC = ROOT / "docs" / "architecture.md"


def _functions(path: Path) -> set[str]:
    tree = ast.parse(path.read_text(encoding="utf-8"))
    return {n.name for n in ast.walk(tree) if isinstance(n, (ast.FunctionDef, ast.AsyncFunctionDef))}


def test_named_tests_exist() -> None:
    text = DOC.read_text(encoding="utf-8")
    missing = []
    for path, name in re.findall(r"(tests/[\w/]+\.py)(?:::(\w+))?", text):
        if not (ROOT / path).is_file():
            missing.append(path)
        elif name and name not in _functions(ROOT / path):
            missing.append(f"{path}::{name}")
    assert not missing, f"docs/architecture.md names what does not exist: {missing}"


def test_mavlink_recipe_names_real_helpers() -> None:
    """The "How to add a MAVLink command" section's API: the names it tells a reader to call."""
    from topgimbal.links import mav as _mav
    from topgimbal.mavlink import commands

    section = DOC.read_text(encoding="utf-8").split("## How to add a MAVLink command", 1)[1].split("\n## ", 1)[0]
    for name in ("mav_id", "msg_id"):
        assert f"{name}(" in section and callable(getattr(_mav, name))
    for name in ("denied", "unsupported", "rejected", "Outcome", "Command", "Dispatcher"):
        assert name in section and hasattr(commands, name)
    for name in ("whole", "finite", "has", "retransmits"):
        assert name in section and hasattr(commands.Command, name)
    assert "register(" in section and hasattr(commands.Dispatcher, "register")
