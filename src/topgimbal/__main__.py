"""`python -m topgimbal ...`: the same as the `topgimbal` command."""

from __future__ import annotations

from .cli.main import main

if __name__ == "__main__":
    raise SystemExit(main())
