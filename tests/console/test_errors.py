"""What the page is told when an op fails: `describe_error` picks the first kind in ERROR_KINDS
that matches, so a subclass is never reported as its base."""

from __future__ import annotations

import asyncio

import pytest

from topgimbal.console.ops import OpError, ReadOnlyError, describe_error
from topgimbal.errors import DeviceError, FieldValueError, RequestTimeoutError, TopGimbalError, TransportError

pytestmark = pytest.mark.virtual


@pytest.mark.parametrize(
    ("exc", "kind", "text"),
    [
        (DeviceError("no"), "device", "The camera refused the zoom: no"),
        (RequestTimeoutError("after 3 tries"), "timeout", "No answer from the camera to the zoom: after 3 tries"),
        (asyncio.TimeoutError(), "timeout", "No answer from the camera to the zoom: timed out"),
        (TransportError("closed"), "link", "Link error during the zoom: closed"),
        (OpError("bad op"), "op", "bad op"),  # also a ValueError: its own kind first
        (ReadOnlyError("watching"), "readonly", "Not sent (the zoom): watching"),
        (TopGimbalError("other"), "error", "the zoom: other"),
        (ValueError("x"), "value", "Invalid arguments for the zoom: x"),
        (RuntimeError("boom"), "internal", "the zoom failed: RuntimeError: boom"),
    ],
)
def test_each_error_gets_its_kind_and_message(exc: BaseException, kind: str, text: str) -> None:
    assert describe_error(exc, "the zoom") == (kind, text)


def test_a_field_error_is_a_value_error_of_its_own_kind() -> None:
    kind, text = describe_error(FieldValueError("zoom", 99, "0..30"))
    assert kind == "value" and text.startswith("Invalid value for the command: ")
