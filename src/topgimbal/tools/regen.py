"""Regenerate every file made from the catalog, or check that none is stale: one command for all.

    python -m topgimbal.tools.regen            # rewrite what changed
    python -m topgimbal.tools.regen --check    # exit 1 naming each stale file (CI, `make test`)
    python -m topgimbal.tools.regen --list     # what is generated, from what

`make docs` runs the first and `make test` the second. REGISTRY lists every generated file: its
path in the repository and the function that renders it, named as "module:function" and imported
only when it runs, so this driver sits in tools/ without importing the layers above it (wire/ for
the dissector, cli/ for the command index). A producer returns the text of one file, or a mapping
of file name -> text for a directory; a `section` target's producer gets the file's current text
and returns it with its generated part renewed (docs/simulator.md's model behaviour tables, in a
hand-written page). The next generator is one more `Target` row. Generated files are marked
`linguist-generated` in `.gitattributes` (a test checks every target but a section is)."""

from __future__ import annotations

import argparse
import importlib
import sys
from collections.abc import Callable, Mapping
from dataclasses import dataclass
from pathlib import Path

ROOT = Path(__file__).resolve().parents[3]  # the repository (src/topgimbal/tools/regen.py)


@dataclass(frozen=True)
class Target:
    name: str
    path: str  # relative to the repository; a directory when the producer returns a mapping
    producer: str  # "module:function", called with no arguments (a section: with the file's text)
    what: str
    section: bool = False  # the producer renews a part of a hand-written file

    def render(self, root: Path = ROOT) -> dict[Path, str]:
        """Every file of this target and its text."""
        module, _, func = self.producer.partition(":")
        produce: Callable[..., str | Mapping[str, str]] = getattr(importlib.import_module(module), func)
        out = produce((root / self.path).read_text(encoding="utf-8")) if self.section else produce()
        if isinstance(out, str):
            return {Path(self.path): out}
        return {Path(self.path) / name: text for name, text in out.items()}


REGISTRY: tuple[Target, ...] = (
    Target("protocol-doc", "docs/protocol.md", "topgimbal.tools.gendocs:render", "the protocol reference"),
    Target(
        "dissector", "contrib/wireshark/topgimbal.lua", "topgimbal.wire.dissector:generate_dissector",
        "the Wireshark Lua dissector",
    ),
    Target("c-tables", "c/generated", "topgimbal.tools.cgen:render", "libtopgimbal's catalog tables"),
    Target(
        "cli-index", "src/topgimbal/cli/command_index.py", "topgimbal.cli.main:index_text",
        "the CLI's subcommand index (a fast start)",
    ),
    Target(
        "request-types", "src/topgimbal/client/catalog_types.pyi", "topgimbal.tools.typestubs:render",
        "request()'s typed signature per command (mypy)",
    ),
    Target(
        "camera-definitions", "contrib/camera-definitions", "topgimbal.camdef.definition:all_definitions",
        "the MAVLink camera definitions, one per model and lens",
    ),
    Target(
        "sim-behaviour", "docs/simulator.md", "topgimbal.sim.behaviour:replace_section",
        "the simulator page's model behaviour tables (a section)", section=True,
    ),
)  # fmt: skip


def stale(targets: tuple[Target, ...] = REGISTRY, root: Path = ROOT) -> dict[Path, str]:
    """The files that differ from what their producer renders now, with the new text."""
    out: dict[Path, str] = {}
    for target in targets:
        for rel, text in target.render(root).items():
            path = root / rel
            current = path.read_bytes() if path.exists() else None
            if current != text.encode("utf-8"):
                out[rel] = text
    return out


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("names", nargs="*", metavar="NAME", help="only these targets (default: all; see --list)")
    ap.add_argument("--check", action="store_true", help="write nothing; exit 1 when a file is stale")
    ap.add_argument("--list", action="store_true", help="list the targets")
    ap.add_argument("--root", type=Path, default=ROOT, help="the repository (default: this checkout)")
    args = ap.parse_args(argv)
    known = {t.name: t for t in REGISTRY}
    if args.list:
        for t in REGISTRY:
            print(f"{t.name:<13} {t.path:<36} {t.what} ({t.producer})")
        return 0
    unknown = [n for n in args.names if n not in known]
    if unknown:
        print(f"regen: unknown target {', '.join(unknown)}; known: {', '.join(known)}", file=sys.stderr)
        return 2
    targets = tuple(known[n] for n in args.names) if args.names else REGISTRY
    changed = stale(targets, args.root)
    if args.check:
        for rel in changed:
            print(f"regen: {rel} is stale", file=sys.stderr)
        if changed:
            print("regen: run `make docs` (python -m topgimbal.tools.regen) and commit the result", file=sys.stderr)
            return 1
        print(f"regen: {len(targets)} targets current")
        return 0
    for rel, text in changed.items():
        path = args.root / rel
        path.parent.mkdir(parents=True, exist_ok=True)
        path.write_text(text, encoding="utf-8")
        print(f"regen: wrote {rel}")
    print(f"regen: {len(targets)} targets, {len(changed)} files rewritten")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
