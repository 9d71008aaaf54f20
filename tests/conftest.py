"""The suite's tiers, marked at collection (pyproject.toml registers them; README, Development):

- `external`: drives a program outside Python (Chromium, ffmpeg, MAVProxy, MAVSDK, SITL, tshark,
  exiftool, a C compiler);
- `loopback`: real sockets on 127.0.0.1/::1, a pty, or a child process (real waiting);
- `virtual`: everything else: memory transport or a fake clock, no socket, no child process; its
  coroutines run on looptime's virtual-time loop.

A test's tier is read from its own source, its module's other code (imports, helpers, constants:
not the module's other tests) and the sources of the fixtures it uses (code that names a loopback
address, a child process or an external program is not virtual), so no test file has to mark
itself, and one loopback test does not take its module's memory:// tests out of the virtual tier; `pytest.mark.loopback`/`external` on a test still wins. The rule is
checked where it matters: a test counted as virtual that opens an IP socket or starts a process
fails at once, saying so (`_virtual_guard`), so `make check` can never quietly wait on a network.
"""

from __future__ import annotations

import ast
import inspect
import re
import socket
import subprocess
from collections.abc import Iterator
from functools import cache
from pathlib import Path
from typing import Any

import pytest

TIERS = ("virtual", "loopback", "external")

# Words in a test module (or a fixture it uses) that make it external: the programs it drives.
EXTERNAL = re.compile(
    r"chromium|playwright|ffmpeg|ffprobe|ffplay|tshark|text2pcap|editcap|exiftool|mavsdk|MAVProxy"
    r"|mavproxy|\bsitl\b|SITL|ardupilot|ArduPilot|\bclang\b|\bgcc\b|shutil\.which",
)
# ... and the ones that make it loopback: an address, a socket, a pty, a child process, a server.
LOOPBACK = re.compile(
    r"127\.0\.0\.1|::1|localhost|socket\.|open_connection|create_server|create_datagram_endpoint|"
    r"start_server|\bpty\b|openpty|subprocess|sys\.executable|ClientSession|BackgroundConsole|ConsoleServer|"
    r"sim_factory|rig_factory|\brig\b|\budp=|\btcp=|start_udp|start_tcp|\.bound_port|Bridge\(|"
    r"serve\(|zenoh|Zenoh|\bLOOP\b|UdpClient|listen=\{",
)


@cache
def _source(path: str) -> str:
    try:
        return Path(path).read_text(encoding="utf-8")
    except OSError:
        return ""


@cache
def _function_source(func: Any) -> str:
    try:
        return inspect.getsource(func)
    except (OSError, TypeError):
        return ""


@cache
def _test_spans(path: str) -> tuple[str, tuple[tuple[str, int, int], ...]]:
    """A module's source and the (name, first line, last line) of each test function in it, its
    decorators included (top level or in a class)."""
    text = _source(path)
    try:
        tree = ast.parse(text)
    except SyntaxError:
        return text, ()
    spans = []
    for node in ast.walk(tree):
        if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef)) and node.name.startswith("test"):
            first = min([node.lineno] + [d.lineno for d in node.decorator_list])
            spans.append((node.name, first, node.end_lineno or node.lineno))
    return text, tuple(spans)


@cache
def _module_context(path: str, test_name: str) -> str:
    """What a test's tier is read from in its module: the module without the other tests' bodies
    (its helpers, constants and imports stay), so that one loopback test does not take a module's
    memory:// tests out of the virtual tier."""
    text, spans = _test_spans(path)
    lines = text.splitlines()
    drop = set()
    for name, first, last in spans:
        if name != test_name:
            drop.update(range(first - 1, last))
    return "\n".join(line for i, line in enumerate(lines) if i not in drop)


def _tier(item: pytest.Item) -> str:
    own = {m.name for m in item.iter_markers() if m.name in TIERS}
    if own:  # a mark by hand wins; the slowest it names
        return max(own, key=TIERS.index)
    if item.get_closest_marker("browser") is not None or {"browser", "page"} & set(item.fixturenames):
        return "external"
    name = getattr(getattr(item, "function", None), "__name__", item.name.split("[")[0])
    texts = [_module_context(str(item.path), name)]
    info = getattr(item, "_fixtureinfo", None)
    for defs in info.name2fixturedefs.values() if info is not None else ():
        for fixturedef in defs:
            code = str(getattr(fixturedef.func, "__code__", ""))
            if "site-packages" not in code and fixturedef.argname != "_virtual_guard":
                texts.append(_function_source(fixturedef.func))
    if any(EXTERNAL.search(t) for t in texts):
        return "external"
    if item.get_closest_marker("integration") is not None or any(LOOPBACK.search(t) for t in texts):
        return "loopback"
    return "virtual"


def pytest_collection_modifyitems(config: pytest.Config, items: list[pytest.Item]) -> None:
    for item in items:
        tier = _tier(item)
        if item.get_closest_marker(tier) is None:
            item.add_marker(getattr(pytest.mark, tier))
        # The virtual tier's coroutines run on looptime's virtual-time loop: their sleeps, timeouts
        # and timers take no real time (memory:// delivers through the loop; no socket waits). A
        # test opts out with `pytest.mark.looptime(False)`.
        coroutine = inspect.iscoroutinefunction(getattr(item, "function", None))
        if tier == "virtual" and coroutine and item.get_closest_marker("looptime") is None:
            item.add_marker(pytest.mark.looptime)


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
