"""The public names users import. Changing this list is an API change: do it on purpose."""

from __future__ import annotations

import pytest

import topgimbal

pytestmark = pytest.mark.virtual

PUBLIC = {
    "AsyncClient", "CatalogError", "ChecksumError", "DeviceError", "DeviceModel", "Diagnostic", "Dialect",
    "FieldValueError", "Frame", "FrameError", "FrameParser", "Gimbal", "LengthError", "Message",
    "LinkLostError", "NoAnswerError", "ModelMismatchError",  # issue 35: one base for "no answer"
    "RequestTimeoutError", "TopGimbalError", "TransportError", "UnknownCommandError", "UnsupportedError",
    "__version__", "connect", "decode", "encode", "get_dialect", "get_model", "parse_frame",
    "speedups_enabled",
}  # fmt: skip


def test_public_names_are_pinned() -> None:
    assert set(topgimbal.__all__) == PUBLIC
    for name in PUBLIC:
        assert hasattr(topgimbal, name), name


def test_exceptions_end_in_error_and_share_a_base() -> None:
    for name in PUBLIC:
        obj = getattr(topgimbal, name)
        if isinstance(obj, type) and issubclass(obj, BaseException):
            assert name.endswith("Error") and issubclass(obj, topgimbal.TopGimbalError), name
    assert issubclass(topgimbal.RequestTimeoutError, TimeoutError)
    # A silent address ends in either; both are "no answer" (issue 35.3), and keep their old bases.
    assert issubclass(topgimbal.RequestTimeoutError, topgimbal.NoAnswerError)
    assert issubclass(topgimbal.LinkLostError, topgimbal.NoAnswerError)
    assert issubclass(topgimbal.LinkLostError, topgimbal.TransportError)
    assert issubclass(topgimbal.LinkLostError, ConnectionError)
    assert issubclass(topgimbal.FieldValueError, ValueError)
