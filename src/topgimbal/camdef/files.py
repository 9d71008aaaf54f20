"""Write (or check) the MAVLink camera definitions generated from the catalog, one file per model and
lens, into a directory (the checked-in contrib/camera-definitions).

    python -m topgimbal.camdef.files contrib/camera-definitions
    python -m topgimbal.camdef.files --check contrib/camera-definitions   # exit 1 when stale
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from .definition import all_definitions


def stale(directory: Path) -> list[str]:
    """Files that differ from the catalog, are missing, or are no longer generated."""
    want = all_definitions()
    out = [name for name, text in want.items()
           if not (directory / name).is_file() or (directory / name).read_text(encoding="utf-8") != text]  # fmt: skip
    out += sorted(p.name for p in directory.glob("*.xml") if p.name not in want) if directory.is_dir() else []
    return out


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("directory", type=Path)
    ap.add_argument("--check", action="store_true", help="exit 1 if a file differs from the catalog")
    args = ap.parse_args(argv)
    if args.check:
        bad = stale(args.directory)
        if bad:
            print(f"{args.directory}: out of date: {', '.join(bad)}: run `make docs`", file=sys.stderr)
            return 1
        print(f"{args.directory} is up to date")
        return 0
    args.directory.mkdir(parents=True, exist_ok=True)
    want = all_definitions()
    for old in args.directory.glob("*.xml"):
        if old.name not in want:
            old.unlink()
    for name, text in want.items():
        (args.directory / name).write_text(text, encoding="utf-8")
    print(f"wrote {len(want)} definitions to {args.directory}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
