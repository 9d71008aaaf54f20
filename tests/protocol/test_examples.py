"""protocol.examples: every codec of every dialect has example values, and they survive a round trip."""

from __future__ import annotations

import pytest

from topgimbal.protocol import DIALECT_NAMES, get_dialect
from topgimbal.protocol.examples import example_fields, example_values, values_equal

pytestmark = pytest.mark.virtual


def test_every_codec_has_examples_that_round_trip() -> None:
    seen = 0
    for name in DIALECT_NAMES:
        for spec in get_dialect(name).commands.values():
            for form in spec.forms:
                for f in form.fields:
                    examples = example_values(f.codec)
                    assert examples, (spec.ident, f.name)
                    for value in examples:
                        raw = f.codec.encode(value, f.name)
                        assert values_equal(value, f.codec.decode(raw)), (spec.ident, f.name, value, raw)
                        seen += 1
    assert seen > 500


def test_example_fields_encode_every_request_form() -> None:
    for name in DIALECT_NAMES:
        dialect = get_dialect(name)
        for spec in dialect.commands.values():
            for form in spec.forms:
                if form.direction == "request" and form.fields:
                    data = form.encode(example_fields(form), spec.ident)
                    assert form.decode(data).keys() == {f.name for f in form.fields}
