"""tests/virtual_time.py: a fixture's teardown closes what a looptime test made on that test's
virtual clock. Without it the teardown ran on the real clock (looptime compacts only the test
function's time): a rig's clock jumped by the machine's uptime at the close, its simulator integrated
those hours of physics, and beside two busy loops a bridge's close ran past its 60 s bound."""

from __future__ import annotations

import ast
from pathlib import Path

import pytest

pytest_plugins = ["pytester"]
pytestmark = pytest.mark.loopback  # a child pytest process

HERE = Path(__file__).parent
INI = """[pytest]
asyncio_mode = auto
asyncio_default_fixture_loop_scope = function
"""
MODULE = """import asyncio
import time

import pytest

from virtual_time import Made

seen = {}


@pytest.fixture
async def maker():
    made = Made()

    def make():
        made.note()
        seen["made_at"] = asyncio.get_running_loop().time()

    yield make
    with made.clock():
        loop = asyncio.get_running_loop()
        seen["closed_at"] = loop.time()
        real = time.monotonic()
        await asyncio.sleep(120.0)  # what a close waits for, in virtual seconds
        seen["close_real_s"] = time.monotonic() - real
        seen["slept_virtual_s"] = loop.time() - seen["closed_at"]
    print("SEEN", seen)


@pytest.mark.looptime
async def test_made_on_virtual_time(maker):
    maker()
    await asyncio.sleep(30.0)


async def test_made_on_real_time(maker):
    maker()  # no looptime: the teardown's clock is the real one, as the test's was
"""


def _seen(result: pytest.RunResult) -> dict[str, float]:
    line = next(x for x in result.outlines if "SEEN {" in x)  # after the progress dot
    return ast.literal_eval(line[line.index("SEEN ") + 5 :])  # type: ignore[no-any-return]


def test_a_fixture_closes_on_the_clock_the_test_made_things_on(pytester: pytest.Pytester) -> None:
    pytester.makepyfile(virtual_time=(HERE / "virtual_time.py").read_text(encoding="utf-8"), test_made=MODULE)
    pytester.makeini(INI)
    result = pytester.runpytest_subprocess("-q", "-s", "-p", "no:cacheprovider", "-k", "virtual_time", timeout=240)
    result.assert_outcomes(passed=1)
    seen = _seen(result)
    # the test's 30 virtual seconds, then the close: the same clock, not the machine's uptime
    assert seen["closed_at"] - seen["made_at"] == pytest.approx(30.0, abs=1.0), seen
    # the close's own 120 s wait is virtual too: no real waiting (a real one outlasts the child's bound)
    assert seen["slept_virtual_s"] == pytest.approx(120.0, abs=1.0), seen
    assert seen["close_real_s"] < 60.0, seen


def test_a_real_time_test_keeps_the_real_clock_at_its_close(pytester: pytest.Pytester) -> None:
    module = MODULE.replace("await asyncio.sleep(120.0)", "await asyncio.sleep(0.2)")
    pytester.makepyfile(virtual_time=(HERE / "virtual_time.py").read_text(encoding="utf-8"), test_made=module)
    pytester.makeini(INI)
    result = pytester.runpytest_subprocess("-q", "-s", "-p", "no:cacheprovider", "-k", "real_time", timeout=240)
    result.assert_outcomes(passed=1)
    seen = _seen(result)
    assert seen["close_real_s"] >= 0.19, seen  # a real sleep: the helper left the clock alone
