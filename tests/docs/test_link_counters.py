"""docs/client.md's table of link counters is LinkStats' own metadata: every counter, in order,
with the description the code carries."""

from __future__ import annotations

import re
from pathlib import Path

import pytest

from topgimbal.client import LinkStats

pytestmark = pytest.mark.virtual

DOC = Path(__file__).resolve().parents[2] / "docs" / "client.md"
ROW = re.compile(r"^\| `(\w+)` \| (.+) \|$")


def test_the_docs_table_is_the_counters_metadata() -> None:
    lines = DOC.read_text().splitlines()
    start = lines.index("| counter | what it counts |") + 2  # after the header and its rule
    table = lines[start : lines.index("", start)]
    rows = [m.groups() if (m := ROW.match(line)) else (None, line) for line in table]
    assert rows == list(LinkStats.describe().items())


def test_every_counter_is_described_and_as_dict_keeps_their_order() -> None:
    described = LinkStats.describe()
    assert all(text.strip() for text in described.values())
    assert list(LinkStats().as_dict()) == list(described)
