"""docs/architecture.md's rules, checked: imports point down the layers, and the protocol core
imports nothing outside the standard library."""

from __future__ import annotations

import ast
import sys
from pathlib import Path

PKG = Path(__file__).resolve().parents[1] / "src" / "topgimbal"

# What each layer may import from inside topgimbal (besides itself and errors).
ALLOWED = {
    "_speedups": set(),  # the optional C fast path: a leaf the protocol core may use
    "protocol": set(),
    "transport": {"protocol"},
    "client": {"protocol", "transport", "video"},  # video.lens only (the stream table; tests/video checks)
    "sim": {"protocol"},
    "console": {"protocol", "client", "sim", "video"},  # sim only for `--sim` (in-process camera)
    "video": {"protocol", "sim"},  # renders the simulator's state; relays any camera's RTSP
    "tools": {"protocol", "client", "sim", "console", "_speedups", "video"},
    "mavlink": {"protocol", "client", "video"},  # video.lens only (streams and fields of view from the profile)
    "wire": {"protocol", "transport", "client"},  # client only for the JSONL traffic log format
    "cli": {"protocol", "client", "transport", "sim", "console", "tools", "mavlink", "wire", "video"},
}


def _imports(path: Path) -> list[str]:
    """Absolute module names imported by a file (relative imports resolved)."""
    tree = ast.parse(path.read_text(encoding="utf-8"))
    parts = list(path.relative_to(PKG.parent).with_suffix("").parts)
    if parts[-1] == "__init__":
        parts = parts[:-1]
    out = []
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            out += [a.name for a in node.names]
        elif isinstance(node, ast.ImportFrom):
            if node.level:
                base = parts[: len(parts) - node.level + (1 if path.name == "__init__.py" else 0)]
                out.append(".".join([*base, node.module] if node.module else base))
            elif node.module:
                out.append(node.module)
    return out


def test_layers_import_only_downwards() -> None:
    bad = []
    for layer, allowed in ALLOWED.items():
        for path in (PKG / layer).rglob("*.py"):
            for mod in _imports(path):
                if not mod.startswith("topgimbal."):
                    continue
                target = mod.split(".")[1]
                if target not in (layer, "errors") and target not in allowed:
                    bad.append(f"{path.relative_to(PKG)} imports {mod}")
    assert not bad, "\n".join(bad)


def test_protocol_core_is_standard_library_only() -> None:
    stdlib = sys.stdlib_module_names
    bad = []
    for path in (PKG / "protocol").rglob("*.py"):
        for mod in _imports(path):
            top = mod.split(".")[0]
            if top != "topgimbal" and top not in stdlib and top != "__future__":
                bad.append(f"{path.relative_to(PKG)} imports {mod}")
    assert not bad, "\n".join(bad)
