"""The suite's tiers, declared by each test module (pyproject.toml registers them; README, Development):

- `external`: drives a program outside Python (Chromium, ffmpeg, MAVProxy, MAVSDK, SITL, tshark,
  exiftool, a C compiler);
- `loopback`: real sockets on 127.0.0.1/::1, a pty, or a child process (real waiting);
- `virtual`: everything else: memory transport or a fake clock, no socket, no child process; its
  coroutines run on looptime's virtual-time loop.

Every test module says `pytestmark = pytest.mark.<tier>` (alone or in its list); a test (or a
parameter) may override it with its own mark, the nearest one wins. A module that declares none is a
collection error naming it: a tier read from a test's words (as this file once did, by regex over
the sources) moved tests between tiers when a comment changed. The rule is checked where it
matters: a test declared virtual that opens an IP socket or starts a process fails at once, saying
so (`_virtual_guard`), so `make check` can never quietly wait on a network.
"""

from __future__ import annotations

import inspect
import socket
import subprocess
from collections.abc import Iterator
from typing import Any

import pytest

from cage import pytest_runtest_logreport, pytest_runtest_protocol  # noqa: F401  (its hooks)

TIERS = ("virtual", "loopback", "external")


class TierUndeclaredError(pytest.UsageError):
    """A test module without `pytestmark = pytest.mark.virtual|loopback|external`."""


def _declared(node: pytest.Item | pytest.Collector) -> str | None:
    names = [m.name for m in node.own_markers if m.name in TIERS]
    return max(names, key=TIERS.index) if names else None  # two at one level: the slowest


def _tier(item: pytest.Item) -> str | None:
    """The nearest declaration: the test's own (or its parameter's), its class's, its module's."""
    for node in reversed(item.listchain()):
        tier = _declared(node)
        if tier is not None:
            return tier
        if isinstance(node, pytest.Module):
            return None  # a conftest's or a package's mark would hide which module forgot
    return None


@pytest.hookimpl(tryfirst=True)  # before `-m` deselects by these marks
def pytest_collection_modifyitems(config: pytest.Config, items: list[pytest.Item]) -> None:
    undeclared: set[str] = set()
    tiers = {}
    for item in items:
        module = item.getparent(pytest.Module)
        if module is not None and _declared(module) is None:
            undeclared.add(str(module.path.relative_to(config.rootpath)))
        tiers[item] = _tier(item)
    # Each test carries exactly its own tier: `-m loopback` reads the marks of every level, so a
    # module's mark left above a test that overrides it would put the test in two tiers.
    for item, tier in tiers.items():
        for node in item.listchain():
            node.own_markers[:] = [m for m in node.own_markers if m.name not in TIERS]
        if tier is None:
            continue
        item.add_marker(getattr(pytest.mark, tier))
        # The virtual tier's coroutines run on looptime's virtual-time loop: their sleeps, timeouts
        # and timers take no real time (memory:// delivers through the loop; no socket waits). A
        # test opts out with `pytest.mark.looptime(False)`.
        coroutine = inspect.iscoroutinefunction(getattr(item, "function", None))
        if tier == "virtual" and coroutine and item.get_closest_marker("looptime") is None:
            item.add_marker(pytest.mark.looptime)
    if undeclared:
        raise TierUndeclaredError(
            "these test modules declare no tier: add `pytestmark = pytest.mark.virtual` (or loopback, "
            "external; tests/conftest.py says which is which) to " + ", ".join(sorted(undeclared))
        )


class VirtualTierError(AssertionError):
    """A test counted as virtual used the real network or a child process."""


def _refuse(what: str) -> None:
    raise VirtualTierError(
        f"this test is in the virtual tier (tests/conftest.py) but {what}: mark it "
        "`pytest.mark.loopback` (or `external`), or keep it on memory:// and a fake clock"
    )


@pytest.fixture(autouse=True)
def _virtual_guard(request: pytest.FixtureRequest, monkeypatch: pytest.MonkeyPatch) -> Iterator[None]:
    """In the virtual tier an IP socket that binds or connects, or a child process, is an error."""
    if request.node.get_closest_marker("virtual") is None:
        yield
        return
    real_bind, real_connect, real_connect_ex = socket.socket.bind, socket.socket.connect, socket.socket.connect_ex

    def ip(sock: socket.socket) -> bool:
        return sock.family in (socket.AF_INET, socket.AF_INET6)

    def bind(sock: socket.socket, address: Any) -> None:
        if ip(sock):
            _refuse(f"binds an IP socket to {address!r}")
        real_bind(sock, address)

    def connect(sock: socket.socket, address: Any) -> None:
        if ip(sock):
            _refuse(f"connects an IP socket to {address!r}")
        real_connect(sock, address)

    def connect_ex(sock: socket.socket, address: Any) -> int:
        if ip(sock):
            _refuse(f"connects an IP socket to {address!r}")
        return real_connect_ex(sock, address)

    def popen(*args: Any, **kwargs: Any) -> Any:
        _refuse(f"starts a process ({str(args[1] if len(args) > 1 else kwargs.get('args'))[:80]})")

    monkeypatch.setattr(socket.socket, "bind", bind)
    monkeypatch.setattr(socket.socket, "connect", connect)
    monkeypatch.setattr(socket.socket, "connect_ex", connect_ex)
    monkeypatch.setattr(subprocess.Popen, "__init__", popen)
    yield
