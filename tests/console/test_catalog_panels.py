"""Issue 16, console side: the panels come from the catalog's metadata (roles, groups, fields), not
from lists kept in the page; no branch on a dialect's name anywhere in the console.

Three ways to see it: the sources hold no identifier literal and no dialect name comparison; every
model's page shows exactly the rows its catalog's groups call for, with no error; and a command
the page has never heard of appears in its panel when the catalog gives it a group."""

from __future__ import annotations

import json
import re
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest

from topgimbal.console.catalog_api import catalog_json
from topgimbal.protocol import all_models, get_dialect, get_model

from .conftest import BackgroundConsole, open_console

pytestmark = pytest.mark.external

CONSOLE = Path(__file__).resolve().parents[2] / "src" / "topgimbal" / "console"
VIDEO_FILES = {"video.js", "video.css"}  # the video package's, mounted in the console


def _sources() -> Iterator[Path]:
    for path in sorted(CONSOLE.rglob("*")):
        if path.suffix in (".py", ".js", ".html") and path.name not in VIDEO_FILES:
            yield path


def _identifiers() -> set[str]:
    return {ident for name in ("skydroid", "topotek") for ident in get_dialect(name).commands}


@pytest.mark.loopback
def test_no_identifier_lists_and_no_dialect_branches_in_the_console() -> None:
    idents = _identifiers()
    quoted = re.compile(r"""(?<![\w#])["'`]([A-Z0-9]{3})["'`]""")
    branch = re.compile(r"""dialect(\.name)?\s*(==|===|!=|!==)|["'](skydroid|topotek)["']""")
    found: list[str] = []
    for path in _sources():
        for n, line in enumerate(path.read_text(encoding="utf-8").splitlines(), 1):
            code = line.split("//")[0] if path.suffix == ".js" else line.split("#")[0]
            hits = [m for m in quoted.findall(code) if m in idents]
            if hits or branch.search(code):
                found.append(f"{path.relative_to(CONSOLE)}:{n}: {line.strip()}")
    assert found == [], "\n".join(found)


@pytest.mark.loopback
def test_the_check_would_catch_a_hand_kept_list(tmp_path: Path) -> None:
    """The scan above bites: the lists round one had are found."""
    idents = _identifiers()
    quoted = re.compile(r"""(?<![\w#])["'`]([A-Z0-9]{3})["'`]""")
    old = 'const THERMAL = ["IMG", "TSM", "TMR"]; const x = S.catalog.dialect === "topotek" ? "VSN" : "VER";'
    assert set(quoted.findall(old)) & idents == {"IMG", "TSM", "TMR", "VSN", "VER"}
    assert re.search(r"dialect(\.name)?\s*(==|===)", old)


# -- every model's page ----------------------------------------------------------------------------


def _rowable(cmd: dict[str, Any]) -> bool:
    requests = [f for f in cmd["forms"] if f["direction"] == "request" and f["rw"] in ("w", "r")]
    raw = any(x["kind"] == "raw" for f in cmd["forms"] for x in f["fields"])
    return bool(requests) and not raw


def expected_rows(cat: dict[str, Any]) -> dict[str, list[str]]:
    """What each panel's generated part must hold, worked out here from the catalog alone."""
    cmds = cat["commands"].values()

    def group(name: str, *skip_roles: str) -> list[str]:
        return [c["id"] for c in cmds if c["group"] == name and c["role"] not in skip_roles and _rowable(c)]

    def request(c: dict[str, Any], rw: str) -> dict[str, Any] | None:
        return next((f for f in c["forms"] if f["rw"] == rw and f["direction"] == "request"), None)

    addresses = []
    for c in cmds:
        w, r = request(c, "w"), request(c, "r")
        if c["group"] == "network" and w and r and [x["kind"] for x in w["fields"]] == ["ipv4"] and _rowable(c):
            addresses.append(c["id"])
    return {
        "thermal-settings": group("thermal"),
        "thermal-unsupported": [c["id"] for c in cat["unsupported"].values() if c["group"] == "thermal"],
        "lens-settings": group("lens", "zoom_control", "focus_control"),
        "camera-settings": group("camera", "photo", "recording", "sd_capacity"),
        "vehicle-settings": group("position"),
        "network": addresses,
    }


def _shown(page: Any) -> dict[str, list[str]]:
    return page.evaluate(
        """() => {
          const ids = (box) => [...document.getElementById(box).querySelectorAll(':scope > .cmdrow')]
            .map((r) => r.dataset.cmd);
          const out = {};
          for (const box of ['thermal-settings', 'thermal-unsupported', 'lens-settings', 'camera-settings',
                             'vehicle-settings']) out[box] = ids(box);
          out.network = [...document.querySelectorAll('#network-fields input')].map((i) => i.id.slice(4));
          return out;
        }"""
    )


@pytest.mark.browser
@pytest.mark.integration
@pytest.mark.parametrize("model", sorted(all_models()))
def test_every_model_shows_the_rows_its_catalog_calls_for(
    browser: Any, model: str, artifacts: Path, page_errors: list[str]
) -> None:
    dialect, m = get_model(model)
    expected = expected_rows(json.loads(json.dumps(catalog_json(dialect, m))))
    with BackgroundConsole(model) as bg:
        page = open_console(browser, bg, page_errors)
        try:
            assert _shown(page) == expected
            # loading the page read what it shows and nothing failed
            assert page.get_by_test_id("error-log").inner_text().strip() == "none"
            assert page.locator(".toast.error").count() == 0
        finally:
            page.context.close()
    assert page_errors == [], page_errors


# -- a command the page has never heard of ----------------------------------------------------------


@pytest.mark.browser
@pytest.mark.integration
def test_a_new_command_appears_in_its_group(browser: Any, c12: BackgroundConsole, page_errors: list[str]) -> None:
    """The catalog gains a thermal command and a network address (as a new dialect row would give):
    the page shows them where their group says, with inputs from their fields, and no edit."""
    context = browser.new_context(viewport={"width": 1400, "height": 1100})
    page = context.new_page()
    page.on("pageerror", lambda exc: page_errors.append(str(exc)))
    toy_enum = {
        "name": "glow",
        "kind": "enum",
        "label": "Glow",
        "values": [{"name": "dim", "label": "Dim", "raw": "00"}, {"name": "bright", "label": "Bright", "raw": "01"}],
    }
    toy_ip = {"name": "address", "kind": "ipv4", "label": "Address"}

    def toy(ident: str, title: str, group: str, role: str, field: dict[str, Any]) -> dict[str, Any]:
        return {
            "id": ident,
            "title": title,
            "section": "toy",
            "role": role,
            "group": group,
            "forms": [
                {"rw": "w", "direction": "request", "title": "set", "role": "", "fields": [field]},
                {"rw": "r", "direction": "request", "title": "query", "role": "", "fields": []},
            ],
        }

    def route(r: Any) -> None:
        cat = r.fetch().json()
        cat["commands"]["TZZ"] = toy("TZZ", "Thermal glow", "thermal", "", toy_enum)
        cat["commands"]["NQQ"] = toy("NQQ", "Camera NTP server", "network", "", toy_ip)
        r.fulfill(json=cat)

    page.route("**/api/catalog", route)
    try:
        page.goto(c12.url)
        page.wait_for_selector("body[data-ready='1']", timeout=30_000)
        row = page.get_by_test_id("cmd-TZZ")
        assert row.is_visible() and "Thermal glow" in row.inner_text()
        # a setting shows "not read" until the camera says its value (issue 35.6), then its values
        options = page.get_by_test_id("field-TZZ-glow").locator("option:not([value=''])").all_inner_texts()
        assert options == ["Dim", "Bright"]
        assert page.locator("#thermal-settings > [data-cmd=TZZ]").count() == 1
        assert page.get_by_test_id("net-NQQ").is_visible()
        assert "Camera NTP server" in page.get_by_test_id("panel-network").inner_text()
    finally:
        context.close()
