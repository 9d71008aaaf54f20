"""Running Debian's tshark over captures with the generated dissector loaded."""

from __future__ import annotations

import json
import shutil
import subprocess
from collections.abc import Callable
from pathlib import Path
from typing import Any

TSHARK = shutil.which("tshark") or "/usr/bin/tshark"


def run_tshark(lua: Path | None, capture: Path, *args: str, timeout: float = 120) -> str:
    """tshark's stdout; fails the test with tshark's stderr when it exits non-zero or the
    dissector raised a Lua error."""
    assert Path(TSHARK).exists(), "tshark is not installed: run `make tshark-deps` (make test does)"
    script = ["-X", f"lua_script:{lua}"] if lua else []
    cmd = [TSHARK, "-n", *script, "-r", str(capture), *args]
    proc = subprocess.run(cmd, capture_output=True, timeout=timeout, check=False, encoding="utf-8", errors="replace")
    assert proc.returncode == 0, f"{' '.join(cmd)} exited {proc.returncode}: {proc.stderr}"
    for text in (proc.stdout, proc.stderr):
        assert "Lua Error" not in text and "lua_script" not in text.replace(str(lua), ""), text[:2000]
    return proc.stdout


def top_layers(lua: Path, capture: Path, *args: str) -> list[list[dict[str, Any]]]:
    """Per packet, the list of TOP frames tshark shows (each the `top` subtree as a dict)."""
    out = run_tshark(lua, capture, "-T", "json", "-J", "top", "--no-duplicate-keys", *args)
    packets = json.loads(out) if out.strip() else []
    result = []
    for p in packets:
        layer = p["_source"]["layers"].get("top", [])
        result.append(layer if isinstance(layer, list) else [layer])
    return result


def _walk(node: Any, visit: Callable[[str, Any], bool]) -> None:
    """Call visit(key, value) for every key below `node`; descend where it returns True."""
    if isinstance(node, dict):
        for k, v in node.items():
            if visit(k, v):
                _walk(v, visit)
    elif isinstance(node, list):
        for x in node:
            _walk(x, visit)


def values(node: dict[str, Any], key: str) -> list[Any]:
    """A field's values in a frame's subtree (tshark gives one value or a list)."""
    found: list[Any] = []

    def visit(k: str, v: Any) -> bool:
        if k == key:
            found.extend(v if isinstance(v, list) else [v])
            return False
        return True

    _walk(node, visit)
    return found


def experts(node: dict[str, Any]) -> list[str]:
    """The expert-info abbreviations raised in a frame's subtree."""
    found: list[str] = []

    def visit(k: str, v: Any) -> bool:
        if k.startswith("top.expert."):
            found.append(k)
        return True

    _walk(node, visit)
    return found
