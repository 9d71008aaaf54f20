"""CameraAPI is made of the typed methods themselves, not a restatement of them."""

from __future__ import annotations

import inspect

import pytest

from topgimbal.client import AsyncClient, CameraAPI, Gimbal
from topgimbal.client.methods import api_method

pytestmark = pytest.mark.virtual


def _typed_methods(cls: type) -> dict[str, api_method]:
    out = {}
    for name in dir(cls):
        v = inspect.getattr_static(cls, name)
        if isinstance(v, api_method):
            out[name] = v
    return out


def test_camera_api_members_are_the_clients_own_typed_methods() -> None:
    client, protocol, facade = _typed_methods(AsyncClient), _typed_methods(CameraAPI), _typed_methods(Gimbal)
    assert {"request", "point", "set_angles", "sd_card", "zoom", "identify"} <= set(client)
    # every typed method the client has, the Protocol has, as the very same object (one definition)
    assert set(protocol) == set(client) == set(facade)
    for name, method in client.items():
        assert protocol[name] is method and facade[name] is method, name


def test_a_camera_api_method_keeps_its_signature() -> None:
    sig = inspect.signature(_typed_methods(CameraAPI)["point"].fn)
    assert list(sig.parameters)[1:3] == ["yaw_deg", "pitch_deg"]
    assert sig.parameters["tolerance_deg"].kind is inspect.Parameter.KEYWORD_ONLY
