"""tests/conftest.py's tiers: a test lands in the tier its module (or its own mark) declares, a module
that declares none is refused at collection, and a test declared virtual that opens an IP socket or
starts a process fails, naming the rule."""

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


def _collected(suite: pytest.Pytester, tier: str) -> set[str]:
    return {line for line in suite.runpytest("-q", "--co", "-m", tier).outlines if "::" in line}


def test_each_test_lands_in_the_tier_its_module_declares(suite: pytest.Pytester) -> None:
    suite.makepyfile(
        # a module's words do not decide: this one names an address and a tool, and is virtual
        test_pure="import pytest\n\npytestmark = pytest.mark.virtual\nHOST = '127.0.0.1'  # ffprobe\n\n"
        "def test_sum():\n    assert HOST\n",
        test_net="import pytest\n\npytestmark = [pytest.mark.loopback]\n\ndef test_addr():\n    pass\n",
        test_tool="import pytest\n\npytestmark = pytest.mark.external\n\ndef test_tool():\n    pass\n",
    )
    assert _collected(suite, "virtual") == {"test_pure.py::test_sum"}
    assert _collected(suite, "loopback") == {"test_net.py::test_addr"}
    assert _collected(suite, "external") == {"test_tool.py::test_tool"}


def test_a_tests_own_mark_overrides_its_modules(suite: pytest.Pytester) -> None:
    # the nearest declaration wins, in both directions, for a test and for one parameter
    suite.makepyfile(
        test_mixed=(
            "import pytest\n\npytestmark = pytest.mark.loopback\n\n"
            "def test_udp():\n    pass\n\n"
            "@pytest.mark.virtual\ndef test_memory():\n    pass\n\n"
            "@pytest.mark.parametrize('kind', [pytest.param('memory', marks=pytest.mark.virtual), 'udp'])\n"
            "def test_kinds(kind):\n    pass\n\n"
            "@pytest.mark.external\ndef test_tool():\n    pass\n"
        ),
    )
    assert _collected(suite, "virtual") == {"test_mixed.py::test_memory", "test_mixed.py::test_kinds[memory]"}
    assert _collected(suite, "loopback") == {"test_mixed.py::test_udp", "test_mixed.py::test_kinds[udp]"}
    assert _collected(suite, "external") == {"test_mixed.py::test_tool"}


def test_a_module_that_declares_no_tier_is_a_collection_error_naming_it(suite: pytest.Pytester) -> None:
    suite.makepyfile(
        test_declared="import pytest\n\npytestmark = pytest.mark.virtual\n\ndef test_a():\n    pass\n",
        # a test's own mark is no module declaration: the module's other tests would have none
        test_forgot="import pytest\n\n@pytest.mark.loopback\ndef test_b():\n    pass\n\ndef test_c():\n    pass\n",
    )
    result = suite.runpytest("-q", "--co")
    assert result.ret == pytest.ExitCode.USAGE_ERROR
    result.stderr.fnmatch_lines(["*declare no tier*test_forgot.py*"])
    assert "test_declared.py" not in result.stderr.str()


def test_a_virtual_test_that_binds_an_ip_socket_fails_naming_the_rule(suite: pytest.Pytester) -> None:
    suite.makepyfile(
        test_sneaky=(
            "import socket as s\nimport pytest\n\npytestmark = pytest.mark.virtual\n\n"
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
    suite.makepyfile(
        test_loop="import asyncio\nimport pytest\n\npytestmark = pytest.mark.virtual\n\ndef test_loop():\n    asyncio.run(asyncio.sleep(0))\n"
    )
    suite.runpytest("-q", "-m", "virtual", "-p", "asyncio").assert_outcomes(passed=1)
