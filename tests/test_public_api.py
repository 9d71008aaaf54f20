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
MOVED = {
    "topgimbal.mavlink.cot": "topgimbal.outputs.cot",
    "topgimbal.mavlink.cot_stream": "topgimbal.outputs.cot_stream",
    "topgimbal.mavlink.klv": "topgimbal.outputs.klv",
    "topgimbal.mavlink.klv_record": "topgimbal.outputs.klv_record",
    "topgimbal.mavlink.rtp_out": "topgimbal.outputs.rtp_out",
    "topgimbal.mavlink.endpoints": "topgimbal.links.endpoints",
    "topgimbal.mavlink.memory_link": "topgimbal.links.memory_link",
    "topgimbal.mavlink.zenoh_link": "topgimbal.links.zenoh_link",
    "topgimbal.mavlink.json_shape": "topgimbal.links.json_shape",
    "topgimbal.mavlink.signing": "topgimbal.links.signing",
}


@pytest.mark.parametrize("old", sorted(MOVED))
def test_a_moved_module_keeps_its_old_import_path(old: str) -> None:
    import importlib

    assert importlib.import_module(old) is importlib.import_module(MOVED[old])


def test_the_bridge_package_still_exports_what_moved_below_it() -> None:
    import topgimbal.mavlink as bridge
    from topgimbal.links import endpoints, mav
    from topgimbal.mavlink.endpoints import parse_endpoint  # the old spelling

    assert bridge.parse_endpoint is parse_endpoint is endpoints.parse_endpoint
    assert bridge.EndpointError is endpoints.EndpointError
    assert bridge.MavlinkUnavailableError is mav.MavlinkUnavailableError
