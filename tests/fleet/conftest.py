"""Simulators, free loopback ports and an independent Zenoh session (eclipse-zenoh directly, none of
our code) for the fleet tests. Scouting is always off; every endpoint is tcp/127.0.0.1:PORT."""

from __future__ import annotations

import json
import socket
from collections.abc import AsyncIterator, Callable, Iterator
from typing import Any

import pytest
import zenoh

from topgimbal.sim import Simulator
from waiting import until


def free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return int(s.getsockname()[1])


def raw_session(port: int, mode: str = "client", listen: list[str] | None = None) -> Any:
    """A Zenoh session made with eclipse-zenoh only: what any other program on the network has
    (with `listen`: listening there instead of connecting to `port`)."""
    conf = zenoh.Config()
    conf.insert_json5("mode", json.dumps(mode))
    conf.insert_json5("scouting/multicast/enabled", "false")
    conf.insert_json5("scouting/gossip/enabled", "false")
    if listen is not None:
        conf.insert_json5("listen/endpoints", json.dumps(listen))
    else:
        conf.insert_json5("connect/endpoints", json.dumps([f"tcp/127.0.0.1:{port}"]))
    return zenoh.open(conf)


def raw_call(session: Any, key: str, payload: str | bytes | None, timeout: float = 30.0) -> list[dict[str, Any]]:
    replies = list(session.get(key, payload=payload, timeout=timeout))
    return [json.loads(r.ok.payload.to_string()) for r in replies if r.ok is not None]


async def eventually(check: Callable[[], bool], timeout: float = 20.0, what: str = "condition") -> None:
    await until(what, check, bound_s=timeout)  # tests/waiting.py: its failure shows the last values


@pytest.fixture
async def sims() -> AsyncIterator[Callable[..., Any]]:
    made: list[Simulator] = []

    async def make(n: int, model: str = "C12") -> list[Simulator]:
        out = []
        for _ in range(n):
            sim = Simulator(model)
            await sim.start(udp=[("127.0.0.1", 0)])
            made.append(sim)
            out.append(sim)
        return out

    yield make
    for sim in made:
        await sim.stop()


@pytest.fixture
def zport() -> Iterator[int]:
    yield free_port()
