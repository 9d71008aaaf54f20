"""Running Debian's tshark over captures with the generated dissector loaded."""

from __future__ import annotations

import json
import shutil
import subprocess
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


def values(node: dict[str, Any], key: str) -> list[Any]:
    """A field's values in a frame's subtree (tshark gives one value or a list)."""
    found: list[Any] = []

    def walk(n: Any) -> None:
        if isinstance(n, dict):
            for k, v in n.items():
                if k == key:
                    found.extend(v if isinstance(v, list) else [v])
                else:
                    walk(v)
        elif isinstance(n, list):
            for x in n:
                walk(x)

    walk(node)
    return found


def experts(node: dict[str, Any]) -> list[str]:
    """The expert-info abbreviations raised in a frame's subtree."""
    found: list[str] = []

    def walk(n: Any) -> None:
        if isinstance(n, dict):
            for k, v in n.items():
                if k.startswith("top.expert."):
                    found.append(k)
                walk(v)
        elif isinstance(n, list):
            for x in n:
                walk(x)

    walk(node)
    return found
