"""The helpers the pcap export and the console capture share: which port the host side takes
(`client_port`, from `CLIENT_PORTS`) and the address a URL names (`network_address`)."""

from __future__ import annotations

import pytest

from topgimbal.transport import network_address
from topgimbal.wire.export import HOST_PORT, _endpoints
from topgimbal.wire.ports import CLIENT_PORTS, client_port

pytestmark = pytest.mark.loopback


@pytest.mark.virtual
def test_client_port_comes_from_the_conventions_table() -> None:
    assert CLIENT_PORTS == {("udp", 9004): "topotek"}
    assert client_port("udp", "topotek", HOST_PORT) == 9004
    assert client_port("tcp", "topotek", HOST_PORT) == HOST_PORT  # the convention is UDP only
    assert client_port("udp", "skydroid", 1234) == 1234


@pytest.mark.parametrize(
    ("url", "expected"),
    [
        ("udp://127.0.0.1:5000", ("udp", "127.0.0.1", 5000)),
        ("tcp://[::1]:7000", ("tcp", "::1", 7000)),
        ("serial:///dev/ttyUSB0?baud=115200", None),
        ("udp://127.0.0.1", None),  # no port
        ("not a url", None),
        ("", None),
    ],
)
def test_network_address(url: str, expected: tuple[str, str, int] | None) -> None:
    assert network_address(url) == expected


def test_export_endpoints_from_a_log_header() -> None:
    # TOPOTEK over UDP: the host listens on its conventional 9004 ...
    assert _endpoints({"dialect": "topotek", "url": "udp://[::1]:42000"}) == ("udp", ("::1", 9004), ("::1", 42000))
    # ... unless the device itself is on 9004; SkyDroid has no convention.
    assert _endpoints({"dialect": "topotek", "url": "udp://127.0.0.1:9004"})[1] == ("127.0.0.1", HOST_PORT)
    assert _endpoints({"dialect": "skydroid", "url": "tcp://127.0.0.1:5000"}) == (
        "tcp",
        ("127.0.0.1", HOST_PORT),
        ("127.0.0.1", 5000),
    )
    # No usable URL: the dialect's first documented UDP port (never the host's 9004).
    transport, host, device = _endpoints({"dialect": "topotek", "url": "serial:///dev/ttyUSB0"})
    assert transport == "udp" and device[1] != 9004 and host == ("127.0.0.1", 9004)
