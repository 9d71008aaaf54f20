"""`memory:NAME`, the in-process MAVLink link (links/memory_link.py): parsed like the other
endpoint forms, bytes both ways through the event loop, peers by name, and bounded in names, peers
and queued bytes. Virtual tier: no socket, the timers on looptime's clock."""

from __future__ import annotations

import asyncio
from collections.abc import Hashable
from typing import Any

import pytest

from topgimbal.links import base as link_base
from topgimbal.links import memory_link
from topgimbal.links.endpoints import FORMS, EndpointError, Link, make_link, parse_endpoint
from topgimbal.links.memory_link import MAX_QUEUED_BYTES, MemoryLink, connect_memory

from .virtual import MemPeer, fresh_name

pytestmark = pytest.mark.virtual


class Recorder:
    """on_data / on_gone for a link; `accept` is what on_data answers (False: nothing signed)."""

    def __init__(self) -> None:
        self.got: list[tuple[Hashable, bytes]] = []
        self.gone: list[Hashable] = []
        self.accept = True

    def on_data(self, _link: Link, peer: Hashable, data: bytes) -> bool:
        self.got.append((peer, data))
        return self.accept

    def on_gone(self, _link: Link, peer: Hashable) -> None:
        self.gone.append(peer)


async def started(name: str, rec: Recorder, max_peers: int = 4) -> Link:
    link = make_link(f"memory:{name}", rec.on_data, rec.on_gone, max_peers)
    await link.start()
    return link


def test_memory_is_an_endpoint_form() -> None:
    spec = parse_endpoint(" memory:gcs-1.a_b ")
    assert (spec.kind, spec.device, spec.host, str(spec)) == ("memory", "gcs-1.a_b", "", "memory:gcs-1.a_b")
    assert "memory:NAME" in FORMS
    for bad in ("memory:", "memory:a b", "memory:-x", "memory:" + "n" * 65, "memory:a:b", "memory:/x"):
        with pytest.raises(EndpointError, match="memory:NAME"):
            parse_endpoint(bad)
    assert isinstance(make_link("memory:x", Recorder().on_data, Recorder().on_gone), MemoryLink)


async def test_bytes_go_both_ways_through_the_loop() -> None:
    rec, name = Recorder(), fresh_name("t")
    link = await started(name, rec)
    heard: dict[str, list[bytes]] = {"a": [], "b": []}
    a = connect_memory(name, heard["a"].append)
    b = connect_memory(name, heard["b"].append)
    assert link.peer_count == 2 and a.peer != b.peer
    assert a.send(b"from a") and b.send(b"from b")
    assert rec.got == []  # handed over through the loop, not called in place
    await asyncio.sleep(0)
    assert rec.got == [(a.peer, b"from a"), (b.peer, b"from b")]
    link.send(b"to all")
    link.send_to(b.peer, b"to b")
    await asyncio.sleep(0)
    assert heard == {"a": [b"to all"], "b": [b"to all", b"to b"]}
    assert (link.bytes_in, link.bytes_out, a.bytes_out, b.bytes_in) == (12, 16, 6, 10)
    a.close()
    assert rec.gone == [a.peer] and link.peer_count == 1
    assert not a.send(b"after close")
    await link.close()


async def test_a_name_is_one_link_and_free_again_when_it_closes() -> None:
    rec, name = Recorder(), fresh_name("t")
    link = await started(name, rec)
    with pytest.raises(EndpointError, match="in use"):
        await started(name, Recorder())
    end = connect_memory(name)
    closed: list[bool] = []
    end.on_close = lambda: closed.append(True)
    await link.close()
    assert end.closed and closed == [True] and not end.send(b"x")
    with pytest.raises(EndpointError, match="no such MAVLink link"):
        connect_memory(name)
    again = await started(name, rec)
    connect_memory(name)
    await again.close()


async def test_peers_are_bounded_and_a_silent_one_gives_its_place(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setattr(link_base, "PEER_TIMEOUT_S", 30.0)
    rec, name = Recorder(), fresh_name("t")
    link = await started(name, rec, max_peers=2)
    quiet, talker = connect_memory(name), connect_memory(name)
    with pytest.raises(EndpointError, match="already 2 peers"):
        connect_memory(name)
    assert link.refused_peers == 1
    await asyncio.sleep(20.0)
    talker.send(b"still here")
    await asyncio.sleep(11.0)  # the quiet end: 31 s without a word, the talker 11 s
    fresh = connect_memory(name)
    assert quiet.closed and not talker.closed and rec.gone == [quiet.peer]
    assert link.peer_count == 2 and fresh.peer not in (quiet.peer, talker.peer)
    await link.close()


async def test_queued_bytes_are_bounded() -> None:
    rec, name = Recorder(), fresh_name("t")
    link = await started(name, rec)
    heard: list[bytes] = []
    end = connect_memory(name, heard.append)
    chunk = b"\xfd" * 1000
    sent = sum(end.send(chunk) for _ in range(400))  # no yield: nothing delivered yet
    assert sent == MAX_QUEUED_BYTES // len(chunk) and end.dropped == 400 - sent
    for _ in range(400):
        link.send(chunk)
    assert link.dropped_out == 400 - sent
    await asyncio.sleep(0)
    assert len(rec.got) == sent and len(heard) == sent
    assert end.send(chunk)  # delivered: room again
    await link.close()


async def test_with_a_signing_key_a_peer_hears_nothing_until_accepted() -> None:
    rec, name = Recorder(), fresh_name("t")
    link = await started(name, rec)
    link.needs_trust = True
    heard: list[bytes] = []
    end = connect_memory(name, heard.append)
    rec.accept = False  # the node found nothing signed with its key
    end.send(b"unsigned")
    await asyncio.sleep(0)
    link.send(b"telemetry")
    await asyncio.sleep(0)
    assert heard == [] and link.dropped_out == 1
    rec.accept = True
    end.send(b"signed")
    await asyncio.sleep(0)
    link.send(b"telemetry")
    await asyncio.sleep(0)
    assert heard == [b"telemetry"]
    await link.close()


async def test_the_names_in_a_process_are_bounded(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setattr(memory_link, "MAX_LINKS", len(memory_link._LINKS) + 1)
    rec = Recorder()
    first = await started(fresh_name("t"), rec)
    with pytest.raises(EndpointError, match="memory links are open"):
        await started(fresh_name("t"), rec)
    await first.close()


async def test_a_node_and_a_peer_exchange_mavlink(vrig_maker: Any) -> None:
    """The link under the real node: simulator, bridge and peer on memory links; a REQUEST_MESSAGE answered."""
    vrig = await vrig_maker("C12")
    info = await vrig.peer.request(154, 283, "GIMBAL_DEVICE_INFORMATION")
    assert info.model_name == "C12"
    assert vrig.bridge.node.links[0].peer_count == 1


async def test_with_a_signing_key_an_unsigned_peer_hears_nothing(vrig_maker: Any) -> None:
    """The node's signing rule on this link: only a peer whose bytes it accepted (signed with the
    key) gets telemetry; an unsigned one is heard, refused, and told nothing."""
    key = bytes(range(32))
    vrig = await vrig_maker("C12", signing_key=key, stream_hz=5.0, attitude_hz=1.0)
    plain = await MemPeer(sysid=203).join(vrig.link)
    await asyncio.sleep(5.0)
    assert plain.messages == [] and vrig.bridge.node.unsigned_in >= 1
    info = await vrig.peer.request(154, 283, "GIMBAL_DEVICE_INFORMATION")  # the signed peer: served
    assert info.model_name == "C12" and plain.messages == []
    plain.close()
