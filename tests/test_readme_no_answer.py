"""README's first Python example against an address where nothing answers ends in the exception
the README names (issue 35.3: it named RequestTimeoutError and raised LinkLostError)."""

from __future__ import annotations

import asyncio
import re
import socket
from pathlib import Path

import pytest

import topgimbal

pytestmark = pytest.mark.loopback

README = Path(__file__).resolve().parents[1] / "README.md"


def _example_and_named_error() -> tuple[str, str]:
    text = README.read_text(encoding="utf-8")
    named = re.search(r"the first request ends in a\s+`(?:topgimbal\.)?(\w+Error)`", text)
    block = re.search(r"```python\n(.*?)```", text, re.S)
    assert named and block, "README: the example or the sentence naming its error is gone"
    return block.group(1), named.group(1)


@pytest.mark.parametrize("kind", ["silent", "closed"])
def test_the_readme_example_against_an_empty_port_raises_what_the_readme_says(kind: str) -> None:
    code, name = _example_and_named_error()
    expected = getattr(topgimbal, name)
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as s:
        s.bind(("127.0.0.1", 0))  # silent: bound, never answers; closed: nothing bound (ICMP unreachable)
        port = s.getsockname()[1]
        if kind == "closed":
            s.close()
        code = code.replace("udp://127.0.0.1:5000", f"udp://127.0.0.1:{port}")
        async_part, sync_part = code.split("asyncio.run(main())", 1)
        scope: dict[str, object] = {}
        exec(compile(async_part, str(README), "exec"), scope)  # defines main()
        with pytest.raises(expected) as info:
            asyncio.run(scope["main"]())  # type: ignore[operator]
        assert "127.0.0.1" in str(info.value)
        with pytest.raises(expected):  # the blocking facade, the example's second half
            exec(compile(async_part.split("async def", 1)[0] + sync_part, str(README), "exec"), {})
