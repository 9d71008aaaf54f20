"""camdef/pacing.py: one camera-definition download at a time (MAVSDK 4.1 deadlocks when a
CAMERA_INFORMATION reaches it during one). The pacer's rules on virtual time; the MAVSDK tests
(test_mavsdk*.py, test_multi.py, each with a cold MAVSDK cache) are what it is for."""

from __future__ import annotations

import asyncio
import logging
from dataclasses import dataclass, field

import pytest

from topgimbal.camdef.pacing import EXPECT_S, FORGET_S, MAX_HOLD_S, SETTLE_S, FetchPacer
from topgimbal.clock import monotonic

pytestmark = pytest.mark.virtual


@dataclass
class FakeServer:
    """What the pacer reads of http.DefinitionServer."""

    active: int = 0
    last_closed_at: float = float("-inf")
    served_at: dict[str, float] = field(default_factory=dict)

    def download(self, name: str) -> None:
        self.served_at[name] = monotonic()
        self.last_closed_at = monotonic()


async def test_an_announced_file_holds_the_next_until_it_is_fetched_and_settled() -> None:
    server = FakeServer()
    pacer = FetchPacer(server)
    assert pacer.quiet()
    pacer.announce("a.xml")
    assert not pacer.quiet()  # its download may be on the way
    await asyncio.sleep(0.2)
    server.active = 1  # the client connected
    await asyncio.sleep(EXPECT_S)  # longer than expect_s, but a download runs
    assert not pacer.quiet()
    server.active = 0
    server.download("a.xml")
    assert not pacer.quiet()  # the client still finishes its end
    await asyncio.sleep(SETTLE_S)
    assert pacer.quiet()


async def test_a_file_never_fetched_stops_holding_after_expect_s_and_is_not_waited_for_again() -> None:
    pacer = FetchPacer(FakeServer())
    pacer.announce("a.xml")
    await asyncio.sleep(EXPECT_S * 0.9)
    assert not pacer.quiet()
    await asyncio.sleep(EXPECT_S * 0.2)
    assert pacer.quiet()  # the client has it (or never fetches)
    pacer.announce("a.xml")
    assert pacer.quiet()  # the same file again: not waited for
    pacer.announce("b.xml")
    assert not pacer.quiet()  # another file is
    await asyncio.sleep(FORGET_S + EXPECT_S)
    assert pacer.quiet()
    pacer.announce("a.xml")
    assert not pacer.quiet()  # forgotten: a client that connects now may be a cold one


async def test_turns_are_first_come_first_served_and_each_waits_for_the_one_before() -> None:
    server = FakeServer()
    pacer = FetchPacer(server)
    went: list[tuple[str, float]] = []
    t0 = monotonic()

    async def inform(name: str) -> None:
        await pacer.turn(name)
        went.append((name, monotonic() - t0))

    tasks = [asyncio.ensure_future(inform(n)) for n in ("a.xml", "b.xml", "c.xml")]
    await asyncio.sleep(0.3)
    assert [n for n, _ in went] == ["a.xml"]  # the others wait for a's download
    server.download("a.xml")  # fetched at 0.3 s
    await asyncio.sleep(SETTLE_S + 0.2)
    assert [n for n, _ in went] == ["a.xml", "b.xml"]
    await asyncio.gather(*tasks)  # nobody fetches b: c goes expect_s after b
    (_, ta), (_, tb), (_, tc) = went
    assert ta == 0.0
    assert 0.3 + SETTLE_S <= tb < 0.3 + SETTLE_S + 0.1
    assert tb + EXPECT_S <= tc < tb + EXPECT_S + 0.1
    assert pacer.held == 2 and pacer.overdue == 0


async def test_a_waiter_goes_after_max_hold_s_with_a_warning(caplog: pytest.LogCaptureFixture) -> None:
    server = FakeServer(active=1)  # a download that never ends
    pacer = FetchPacer(server)
    t0 = monotonic()
    with caplog.at_level(logging.WARNING, "topgimbal.mavlink"):
        await pacer.turn("a.xml")
    assert MAX_HOLD_S <= monotonic() - t0 < MAX_HOLD_S + 0.1
    assert pacer.overdue == 1
    assert "announced after 10.0 s although a download may still run" in caplog.text


async def test_a_cancelled_waiter_gives_its_turn_up() -> None:
    server = FakeServer()
    pacer = FetchPacer(server)
    pacer.announce("a.xml")
    first = asyncio.ensure_future(pacer.turn("b.xml"))
    second = asyncio.ensure_future(pacer.turn("c.xml"))
    await asyncio.sleep(0.1)
    first.cancel()  # its camera closed
    await asyncio.gather(first, return_exceptions=True)
    server.download("a.xml")
    await asyncio.wait_for(second, SETTLE_S + 0.2)  # not stuck behind the cancelled one


async def test_every_definition_server_of_the_node_counts() -> None:
    one, two = FakeServer(), FakeServer()
    pacer = FetchPacer(one)
    pacer.add(two)
    pacer.add(two)
    assert pacer.servers == [one, two]
    two.active = 1
    assert not pacer.quiet()
    two.active = 0
    pacer.announce("c12-visible.xml")
    two.download("c12-visible.xml")  # the second bridge's server sent it
    await asyncio.sleep(SETTLE_S)
    assert pacer.quiet()
