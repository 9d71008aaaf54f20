"""The host written into the camera-definition URI (issue 32, item 4): `--definition-host` when
given; bound to all interfaces without it, the address of the interface that reaches the peer
asking (a UDP socket's connect() and getsockname(): no packet is sent)."""

from __future__ import annotations

import asyncio
import urllib.request
from typing import Any

import pytest

from topgimbal.mavlink.advertise import Advertiser, peer_host, reaching_address

pytestmark = pytest.mark.loopback

CAMERA = 100


def test_the_address_that_reaches_a_loopback_peer_is_loopback() -> None:
    assert reaching_address("127.0.0.1") == "127.0.0.1"
    assert reaching_address("not an address") is None
    assert peer_host(("udpin:0.0.0.0:14550", ("127.0.0.1", 40000))) == "127.0.0.1"
    assert peer_host(("udpout:127.0.0.1:14550", "out")) is None  # a peer without an address
    assert peer_host(None) is None


def test_bound_to_all_interfaces_the_uri_names_the_interface_that_reaches_the_peer() -> None:
    a = Advertiser("0.0.0.0", None, [])
    assert a.fixed is None
    assert a.host_for(("udpin:0.0.0.0:14550", ("127.0.0.1", 40000))) == "127.0.0.1"
    # no address for the peer (serial, routed through the autopilot): the hosts the links name
    assert Advertiser("0.0.0.0", None, ["127.0.0.1"]).host_for(("serial:/dev/ttyS0", "serial")) == "127.0.0.1"
    # given, or bound to one address: that, whoever asks
    assert Advertiser("0.0.0.0", "gcs-side.example", []).host_for(None) == "gcs-side.example"
    assert Advertiser("127.0.0.1", None, []).host_for(("x", ("10.0.0.9", 1))) == "127.0.0.1"


async def test_definition_host_is_advertised_and_serves_the_file(rig_factory: Any) -> None:
    r = await rig_factory("C12", definition_host="127.0.0.1")
    info = await r.peer.request(CAMERA, 259, "CAMERA_INFORMATION")
    assert info.cam_definition_uri.startswith("http://127.0.0.1:")
    data = await asyncio.to_thread(lambda: urllib.request.urlopen(info.cam_definition_uri, timeout=10).read())
    assert b"<mavlinkcamera" in data
    r2 = await rig_factory("C12", definition_host="camera.local")
    info = await r2.peer.request(CAMERA, 259, "CAMERA_INFORMATION")
    assert info.cam_definition_uri.startswith("http://camera.local:")
