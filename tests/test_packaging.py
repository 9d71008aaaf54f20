"""The package metadata builds without warnings (issue 26, item 8: `make demo` printed setuptools'
"`project.license` as a TOML table is deprecated" three times, once per build step of the editable
install)."""

from __future__ import annotations

import re
from pathlib import Path

import pytest
import tomllib

pytestmark = pytest.mark.virtual

PYPROJECT = tomllib.loads((Path(__file__).resolve().parents[1] / "pyproject.toml").read_text("utf-8"))


def test_license_is_an_spdx_string() -> None:
    assert PYPROJECT["project"]["license"] == "MIT"  # the table form ({text = ...}) warns on setuptools >= 77


def test_build_requires_a_setuptools_that_reads_it() -> None:
    # setuptools < 77 rejects a string license: the build must not pick one of those
    (req,) = [r for r in PYPROJECT["build-system"]["requires"] if r.startswith("setuptools")]
    m = re.fullmatch(r"setuptools>=(\d+)(?:\.\d+)*", req)
    assert m and int(m.group(1)) >= 77, req
