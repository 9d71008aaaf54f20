"""What /api/catalog gives the page beyond the catalog (English labels, vendor terms, reasons
without section numbers), and the example frames the console's docs and page show."""

from __future__ import annotations

import re
from pathlib import Path
from typing import Any

import pytest

from topgimbal.console.catalog_api import catalog_json, field_label, split_label
from topgimbal.errors import FrameError
from topgimbal.protocol import all_models, get_model
from topgimbal.protocol.frame import complete_frame, dissect

pytestmark = pytest.mark.virtual

ROOT = Path(__file__).resolve().parents[2]
CJK = re.compile(r"[\u3000-\u303f\u3400-\u4dbf\u4e00-\u9fff\uff00-\uffef]")


def _catalog(model: str) -> dict[str, Any]:
    dialect, m = get_model(model)
    return catalog_json(dialect, m)


def _fields(cat: dict[str, Any]) -> list[dict[str, Any]]:
    return [f for c in cat["commands"].values() for form in c["forms"] for f in form["fields"]]


@pytest.mark.parametrize("model", sorted(all_models()))
def test_labels_are_english_and_reasons_carry_no_section_numbers(model: str) -> None:
    cat = _catalog(model)
    for f in _fields(cat):
        assert f["label"] and "_" not in f["label"] and not CJK.search(f["label"]), f
        for v in f.get("values", []) + f.get("tokens", []):
            assert v["label"] and not CJK.search(v["label"]), v
            if v.get("vendor_term"):
                assert CJK.search(v["vendor_term"]), v
    for u in cat["unsupported"].values():
        assert "§" not in u["reason"] and u["section"], u
        assert not CJK.search(u["reason"]), u
    assert not CJK.search(cat["dialect_label"]) and cat["dialect_title"]


def test_vendor_terms_are_split_off() -> None:
    img = _catalog("C12")["commands"]["IMG"]
    values = {v["name"]: v for v in img["forms"][0]["fields"][0]["values"]}
    assert (values["white_hot"]["label"], values["white_hot"]["vendor_term"]) == ("White hot", "白热")
    assert (values["black_hot"]["label"], values["black_hot"]["vendor_term"]) == ("Black hot", "黑热")
    ptz = _catalog("C12")["commands"]["PTZ"]
    codes = {v["name"]: v for v in ptz["forms"][0]["fields"][0]["values"]}
    assert codes["center"]["label"] == "Centre" and codes["center"].get("vendor_term") == "回中"


@pytest.mark.parametrize(
    ("label", "split"),
    [
        ("White hot 白热", ("White hot", "白热")),
        ("Centre (回中)", ("Centre", "回中")),
        ("Rainbow 2 彩虹2", ("Rainbow 2", "彩虹2")),
        ("通用", ("", "通用")),
        ("Zoom in 0.5x", ("Zoom in 0.5x", None)),
        ("-20..150 °C", ("-20..150 °C", None)),
    ],
)
def test_split_label(label: str, split: tuple[str, str | None]) -> None:
    assert split_label(label) == split


def test_a_vendor_term_from_the_catalog_is_kept(monkeypatch: pytest.MonkeyPatch) -> None:
    """When the protocol gives enum values their own `vendor_term`, the page uses it as is."""
    from topgimbal.console import catalog_api

    value = {"raw": "01", "name": "white_hot", "label": "White hot", "vendor_term": "白热"}
    assert catalog_api._present_value(value) == value
    only_cjk = catalog_api._present_value({"raw": "00", "name": "general", "label": "通用"})
    assert (only_cjk["label"], only_cjk["vendor_term"]) == ("General", "通用")


@pytest.mark.parametrize(
    ("name", "label"),
    [
        ("interval_s", "Interval"),
        ("avg_temp_c", "Average temperature"),
        ("yaw_rate_deg_s", "Yaw rate"),
        ("lat_deg", "Latitude"),
        ("h_flip", "Horizontal flip"),
        ("remaining_mb", "Remaining"),
        ("uid", "UID"),
        ("x_px", "X"),
        ("spatial_denoise", "Spatial denoise"),
    ],
)
def test_field_label(name: str, label: str) -> None:
    assert field_label(name) == label


def test_reason_names_the_models_that_have_it() -> None:
    tsm = _catalog("C12")["unsupported"]["TSM"]
    assert tsm["reason"] == "the C12 does not support TSM (Thermal scene mode); only the C13 has it"
    assert tsm["section"].startswith("SkyDroid §")


# -- issue 17 item 5, console part: the example frames are right ------------------------------------

FRAME = re.compile(r"#T[Pp][A-Z][A-Z][0-9A-F][rw][A-Z0-9]{3}[0-9A-Za-z!]*")
WRONG_ON_PURPOSE = {"#TPUD2rVER0052"}  # docs/console.md shows it refused: the checksum is 51


def _frames(path: Path) -> set[str]:
    return set(FRAME.findall(path.read_text(encoding="utf-8")))


def test_example_frames_in_the_console_docs_and_page_are_right() -> None:
    docs = ROOT / "docs" / "console.md"
    static = ROOT / "src" / "topgimbal" / "console" / "static"
    shown = _frames(docs) | _frames(static / "index.html") | _frames(static / "app.js")
    assert {"#TPUD2rVER00", "#TPUD2rVER0051"} <= shown
    doc_text = docs.read_text(encoding="utf-8")
    for frame in sorted(shown - WRONG_ON_PURPOSE):
        full = complete_frame(frame).decode("latin-1")  # raises if the example is wrong
        assert dissect(full.encode(), recover_length=False).ok
        if full != frame:  # typed without its checksum: the docs show what is actually sent
            assert full in doc_text, f"{frame} is sent as {full}; say so in docs/console.md"
    for frame in WRONG_ON_PURPOSE:
        assert frame in doc_text
        with pytest.raises(FrameError, match="51"):
            complete_frame(frame)
