"""The bridge greets a peer it has just heard with a HEARTBEAT at once, not at its next beat."""

from __future__ import annotations

from typing import Any

import pytest

from .conftest import Peer

pytestmark = pytest.mark.loopback


async def test_a_new_peer_gets_a_heartbeat_before_the_next_period(rig_factory: Any) -> None:
    # A beat every 10 s: the one sent at start went nowhere (udpin has no peer yet), so a
    # HEARTBEAT within 5 s of the second peer's first message can only be the greeting.
    rig = await rig_factory(heartbeat_hz=0.1)
    late = Peer(sysid=254)
    try:
        await late.connect(rig.bridge.addresses[0][1])
        beat = await late.wait("HEARTBEAT", timeout=5.0)
        assert beat.get_srcSystem() == rig.bridge.config.sysid
    finally:
        late.close()


async def test_a_flood_of_new_peers_does_not_multiply_heartbeats(rig_factory: Any) -> None:
    rig = await rig_factory(heartbeat_hz=0.1)
    port = rig.bridge.addresses[0][1]
    peers = [await Peer(sysid=200 + i).connect(port) for i in range(12)]
    try:
        await peers[-1].wait("HEARTBEAT", timeout=5.0)
        beats = [m for m in peers[0].messages if m.get_type() == "HEARTBEAT"]
        components = len(rig.bridge.services)
        # 12 new peers in a burst: a few greetings (one per GREETING_GAP_S at most), not 12
        assert len(beats) <= 6 * components, len(beats)
    finally:
        for p in peers:
            p.close()
