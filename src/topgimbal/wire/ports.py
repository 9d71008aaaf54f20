"""Which dialect a conversation speaks, decided as everywhere else in topgimbal: by the model
when the user names one, by a documented port when the traffic uses one, else by the frame.

The port table comes from the catalog's device models (their documented endpoints); the only
addition is TOPOTEK's client port 9004, which its document gives as the port a host listens on
(the catalog records it in the SIP endpoint's note, not as an endpoint of the device).
"""

from __future__ import annotations

from functools import cache

from ..protocol import DIALECT_NAMES, Dialect, Frame, Message, get_dialect

# (transport, port) -> dialect for ports a host, not a device, uses by convention.
CLIENT_PORTS: dict[tuple[str, int], str] = {("udp", 9004): "topotek"}


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


def frame_candidates(frame: Frame) -> list[Dialect]:
    """Dialects to try for a frame when nothing else says: TOPOTEK-only traits (the network host
    address P, the #tP/#Tp headers) put TOPOTEK first, otherwise SkyDroid is tried first (the CLI's
    `decode` does the same)."""
    order = list(DIALECT_NAMES)
    if "P" in (frame.src, frame.dst) or frame.header in ("#tP", "#Tp"):
        order = ["topotek", "skydroid"]
    return [get_dialect(n) for n in order]


def decode_frame(frame: Frame, dialect: Dialect | str | None) -> tuple[Dialect, Message]:
    """The frame decoded in `dialect`, or in the first candidate dialect whose forms fit it."""
    if dialect is not None:
        d = get_dialect(dialect)
        return d, d.decode(frame)
    first: tuple[Dialect, Message] | None = None
    for d in frame_candidates(frame):
        msg = d.decode(frame)
        first = first or (d, msg)
        if msg.fields is not None:
            return d, msg
    assert first is not None
    return first
