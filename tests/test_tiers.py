"""tests/conftest.py's tiers: a test lands in the tier its sources say, and a test counted as
virtual that opens an IP socket or starts a process fails, naming the rule."""

from __future__ import annotations

from pathlib import Path

import pytest

pytest_plugins = ["pytester"]
pytestmark = pytest.mark.virtual  # the tool names and addresses below are the fixtures' text, not used

CONFTEST = (Path(__file__).parent / "conftest.py").read_text(encoding="utf-8")
INI = """[pytest]
asyncio_default_fixture_loop_scope = function
markers =
    virtual: v
    loopback: l
    external: e
    integration: i
    browser: b
"""


@pytest.fixture
def suite(pytester: pytest.Pytester) -> pytest.Pytester:
    pytester.makeconftest(CONFTEST)
    pytester.makeini(INI)
    return pytester


def test_each_module_lands_in_the_tier_its_source_says(suite: pytest.Pytester) -> None:
    suite.makepyfile(
        test_pure="def test_sum():\n    assert 1 + 1 == 2\n",
        test_net="HOST = '127.0.0.1'\n\ndef test_addr():\n    assert HOST\n",
        test_tool="import shutil\n\ndef test_tool():\n    assert shutil.which('ffprobe') or True\n",
        test_marked="import pytest\n\n@pytest.mark.loopback\ndef test_marked():\n    pass\n",
    )
    for tier, expected in (("virtual", "test_pure.py"), ("loopback", "test_"), ("external", "test_tool.py")):
        result = suite.runpytest("-q", "--co", "-m", tier)
        names = {line.split("::")[0] for line in result.outlines if "::" in line}
        assert names, (tier, result.outlines)
        assert all(n.startswith(expected) for n in names), (tier, names)
    loopback = suite.runpytest("-q", "--co", "-m", "loopback").outlines
    assert any("test_net.py" in line for line in loopback) and any("test_marked.py" in line for line in loopback)


def test_a_virtual_test_that_binds_an_ip_socket_fails_naming_the_rule(suite: pytest.Pytester) -> None:
    suite.makepyfile(
        test_sneaky=(
            "import socket as s\n\n"
            "def test_bind():\n"
            "    with s.socket(s.AF_INET, s.SOCK_DGRAM) as sock:\n"
            "        sock.bind(('127.0.0.' + '1', 0))\n"
        )
    )
    result = suite.runpytest("-q", "-m", "virtual")
    result.assert_outcomes(failed=1)
    result.stdout.fnmatch_lines(["*VirtualTierError*virtual tier*binds an IP socket*"])


def test_a_virtual_test_may_use_a_socketpair(suite: pytest.Pytester) -> None:
    # the event loop's own self-pipe is an AF_UNIX socketpair: not the network
    suite.makepyfile(test_loop="import asyncio\n\ndef test_loop():\n    asyncio.run(asyncio.sleep(0))\n")
    suite.runpytest("-q", "-m", "virtual", "-p", "asyncio").assert_outcomes(passed=1)


def test_a_test_is_tiered_by_its_own_body_and_the_module_around_it(suite: pytest.Pytester) -> None:
    # one loopback test does not take its neighbours out of the virtual tier; a module-level
    # helper or constant still counts for every test in the module
    suite.makepyfile(
        test_mixed=("def test_memory():\n    assert 'memory://cam'\n\ndef test_udp():\n    assert '127.0.0.1'\n"),
        test_shared="ADDR = '127.0.0.1'\n\ndef test_a():\n    assert ADDR\n\ndef test_b():\n    pass\n",
    )
    virtual = [line for line in suite.runpytest("-q", "--co", "-m", "virtual").outlines if "::" in line]
    assert virtual == ["test_mixed.py::test_memory"], virtual
