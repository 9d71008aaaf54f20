"""One range per model, said the same everywhere, from the profile (issue 26, item 4: the C12's tilt
is +-45 in the library, but the README's model table, docs/console.md and `catalog GAP` said +-90
and docs/client.md's `set_angles(pitch_deg=-90)` failed on the default C12)."""

from __future__ import annotations

import json
import re
from pathlib import Path

import pytest

from topgimbal.cli.main import main
from topgimbal.protocol import all_models, get_model

pytestmark = pytest.mark.virtual

ROOT = Path(__file__).resolve().parents[2]


def said(lo: float, hi: float) -> str:
    """How the docs write a range."""
    if lo == hi == 0:
        return "none"
    return f"±{hi:g}" if lo == -hi else f"{lo:g}..{hi:g}"


def narrowest(model_name: str, axis: str) -> tuple[float, float]:
    """The range the library accepts on `axis`: the profile's, narrowed by its angle command limits."""
    _d, model = get_model(model_name)
    lo, hi = getattr(model, f"{axis}_range_deg")
    for (_ident, field), (a, b) in model.limits.items():
        if field == f"{axis}_deg":
            lo, hi = max(lo, a), min(hi, b)
    return lo, hi


def readme_rows() -> dict[str, list[str]]:
    text = (ROOT / "README.md").read_text("utf-8")
    table = text[text.index("| model | dialect |") :].split("\n\n", 1)[0].splitlines()
    header = [c.strip() for c in table[0].strip("|").split("|")]
    assert header[3:] == ["yaw (deg)", "pitch (deg)", "roll (deg)"]
    rows = {}
    for line in table[2:]:
        cells = [c.strip() for c in line.strip("|").split("|")]
        for name in cells[0].split(" (")[0].split(", "):
            rows[name] = cells[3:]
    return rows


def test_readme_model_table_says_each_profiles_ranges() -> None:
    rows = readme_rows()
    assert set(rows) == set(all_models())
    for name in all_models():
        assert rows[name] == [said(*narrowest(name, axis)) for axis in ("yaw", "pitch", "roll")], name
    assert rows["C12"][1] == "±45"


def test_catalog_names_the_models_that_narrow_a_field(capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["catalog", "GAP", "--dialect", "skydroid"]) == 0
    out = capsys.readouterr().out
    assert "on the C12 (its profile): pitch_deg -45..45" in out and "on the C11 (its profile): pitch_deg -90..10" in out
    assert main(["catalog", "GAM", "--dialect", "skydroid", "--json"]) == 0
    entry = json.loads(capsys.readouterr().out)[0]
    assert entry["model_limits"]["C12"]["pitch_deg"] == [-45.0, 45.0]
    assert "C10" not in entry["model_limits"]  # a model whose profile keeps the catalog's range


def test_client_doc_examples_fit_the_default_c12() -> None:
    """Every set_angles / point example of docs/client.md and the README runs on a C12 (the default)."""
    checked = 0
    for doc in (ROOT / "docs" / "client.md", ROOT / "README.md"):
        for call, args in re.findall(r"\b(set_angles|point)\(([^()]*)\)", doc.read_text("utf-8")):
            values: dict[str, float] = {}
            positional = [a.strip() for a in args.split(",") if a.strip() and "=" not in a]
            for axis, text in zip(("yaw", "pitch"), positional, strict=False):
                if re.fullmatch(r"-?\d+(\.\d+)?", text):
                    values[axis] = float(text)
            for axis, text in re.findall(r"(yaw|pitch|roll)_deg=(-?\d+(?:\.\d+)?)", args):
                values[axis] = float(text)
            for axis, v in values.items():
                lo, hi = narrowest("C12", axis)
                assert lo <= v <= hi, f"{doc.name}: {call}({args}) has {axis} {v}, the C12 takes {lo:g}..{hi:g}"
                checked += 1
    assert checked >= 6


def test_console_doc_says_the_c12_pitch_range() -> None:
    text = (ROOT / "docs" / "console.md").read_text("utf-8")
    assert "C12 ±90°" not in text and "pitch ±45°" in text
