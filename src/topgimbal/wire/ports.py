"""Which dialect a conversation's port implies: the documented ports of the catalog's models.

A port only says which dialect to try first: decoding itself is `protocol.decode_any(frame,
prefer=...)` everywhere (the proxy, `decode --pcap`, and the Lua dissector, which ports the same
rule), so a frame the port's dialect cannot decode is decoded by the other one.

The port table comes from the catalog's device models (their documented endpoints); the only
addition is TOPOTEK's client port 9004, which its document gives as the port a host listens on
(the catalog records it in the SIP endpoint's note, not as an endpoint of the device).
"""

from __future__ import annotations

from functools import cache

from ..protocol import DIALECT_NAMES, get_dialect

# (transport, port) -> dialect for ports a host, not a device, uses by convention.
CLIENT_PORTS: dict[tuple[str, int], str] = {("udp", 9004): "topotek"}


def client_port(transport: str, dialect: str, default: int) -> int:
    """The port a host speaking `dialect` listens on by convention (`CLIENT_PORTS`), else `default`."""
    for (kind, port), name in sorted(CLIENT_PORTS.items()):
        if kind == transport and name == dialect:
            return port
    return default


@cache
def documented_ports() -> dict[tuple[str, int], str]:
    """(transport, port) -> dialect name, for every documented device port and client port."""
    table: dict[tuple[str, int], str] = dict(CLIENT_PORTS)
    for name in DIALECT_NAMES:
        for model in get_dialect(name).models.values():
            for ep in model.endpoints:
                if ep.port is None or ep.kind not in ("udp", "tcp"):
                    continue
                other = table.setdefault((ep.kind, ep.port), name)
                if other != name:
                    raise ValueError(f"{ep.kind} port {ep.port} is documented for both {other} and {name}")
    return table


def dialect_for_ports(transport: str, *ports: int) -> str | None:
    """The dialect a documented port among `ports` implies, or None."""
    table = documented_ports()
    for port in ports:
        name = table.get((transport, port))
        if name is not None:
            return name
    return None
