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


# Modules that moved out of mavlink/ (issue 44): the old import paths are the new modules, so code
# written against them keeps working, and a name imported either way is one object.
from topgimbal._moved import MOVED  # noqa: E402  # one table: every old path is tested


@pytest.mark.parametrize("old", sorted(MOVED))
def test_a_moved_module_keeps_its_old_import_path(old: str) -> None:
    import importlib

    new = importlib.import_module(MOVED[old])
    assert importlib.import_module(old) is new
    assert new.__spec__ is not None and new.__spec__.name == MOVED[old]  # its own spec, not the alias's
    parent, _, leaf = old.rpartition(".")
    assert getattr(importlib.import_module(parent), leaf) is new  # `topgimbal.mavlink.cot` as an attribute


def test_the_old_paths_are_only_those_of_the_table() -> None:
    import importlib

    import topgimbal

    with pytest.raises(ModuleNotFoundError, match=r"topgimbal\.mavlink\.no_such_module"):
        importlib.import_module("topgimbal.mavlink.no_such_module")
    assert topgimbal.mavlink.bridge.Bridge.__module__ == "topgimbal.mavlink.bridge"  # real modules stay real


def test_the_bridge_package_still_exports_what_moved_below_it() -> None:
    import topgimbal.mavlink as bridge
    from topgimbal.links import endpoints, mav
    from topgimbal.mavlink.endpoints import parse_endpoint  # the old spelling

    assert bridge.parse_endpoint is parse_endpoint is endpoints.parse_endpoint
    assert bridge.EndpointError is endpoints.EndpointError
    assert bridge.MavlinkUnavailableError is mav.MavlinkUnavailableError
