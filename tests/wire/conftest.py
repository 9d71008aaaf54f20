"""Fixtures for the wire tests: the generated dissector, written once per session."""

from __future__ import annotations

from pathlib import Path

import pytest

from topgimbal.wire import generate_dissector


@pytest.fixture(scope="session")
def dissector(tmp_path_factory: pytest.TempPathFactory) -> Path:
    path = tmp_path_factory.mktemp("lua") / "topgimbal.lua"
    path.write_text(generate_dissector(), encoding="utf-8")
    return path
