"""docs/simulator.md's model behaviour tables are the model profiles' data, regenerated."""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path

import pytest

from topgimbal.protocol import QUIRKS, all_models
from topgimbal.sim import behaviour

pytestmark = pytest.mark.virtual

DOC = Path(__file__).resolve().parents[2] / "docs" / "simulator.md"


def test_the_tables_in_docs_are_current() -> None:
    text = DOC.read_text(encoding="utf-8")
    assert behaviour.replace_section(text) == text, "run: python -m topgimbal.sim.behaviour docs/simulator.md"
    assert behaviour.main(["--check", str(DOC)]) == 0


def test_every_model_and_quirk_is_listed() -> None:
    section = behaviour.section()
    for name in all_models():
        assert f"| {name} |" in section
    for quirk in QUIRKS:
        assert f"| `{quirk}` |" in section


def test_a_profile_change_makes_the_check_fail(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    doc = tmp_path / "simulator.md"
    doc.write_text(DOC.read_text(encoding="utf-8"), encoding="utf-8")
    models = all_models()
    changed = {**models, "C12": replace(models["C12"], quirks={**models["C12"].quirks, "crlf": True})}
    monkeypatch.setattr(behaviour, "all_models", lambda: changed)
    assert behaviour.main(["--check", str(doc)]) == 1
    assert behaviour.main([str(doc)]) == 0 and behaviour.main(["--check", str(doc)]) == 0
    assert "| `crlf` | every frame the device sends ends with CR LF (some firmware does) | C12 |" in doc.read_text()
