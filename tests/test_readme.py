"""The README's examples, run: the async client example against a simulator on loopback, and the
offline protocol example with the results its comments promise."""

from __future__ import annotations

import asyncio
import re
from pathlib import Path

import pytest

from topgimbal.sim import Simulator

pytestmark = pytest.mark.loopback

README = (Path(__file__).resolve().parents[1] / "README.md").read_text(encoding="utf-8")
BLOCKS = re.findall(r"```python\n(.*?)```", README, flags=re.S)


def test_client_example_runs_against_the_simulator() -> None:
    block = next(b for b in BLOCKS if "topgimbal.connect(" in b)
    # Only the async part: the blocking example opens a serial port that is not on this machine.
    code = block.split("asyncio.run(main())")[0]
    assert "udp://127.0.0.1:5000" in code

    async def run() -> Simulator:
        sim = Simulator("C12", seed=3)
        await sim.start(udp=[("127.0.0.1", 0)])
        try:
            ns: dict[str, object] = {}
            exec(code.replace("udp://127.0.0.1:5000", sim.url), ns)  # the README's own code
            await asyncio.wait_for(ns["main"](), 30)  # type: ignore[operator]
        finally:
            await sim.stop()
        return sim

    sim = asyncio.run(run())
    assert sim.camera.photos_taken == 1 and sim.camera.recording
    assert abs(sim.gimbal.yaw_deg - 30) < 0.6 and abs(sim.gimbal.pitch_deg + 45) < 0.6


@pytest.mark.virtual
def test_offline_example_gives_what_its_comments_say() -> None:
    block = next(b for b in BLOCKS if "from topgimbal import encode, decode" in b)
    ns: dict[str, object] = {}
    exec(block.splitlines()[0], ns)
    for line in block.splitlines()[1:]:
        expr, promised = re.split(r"\s{2,}# ", line, maxsplit=1)  # frames contain '#' too
        value = eval(expr.strip(), ns)
        assert repr(value) == promised.strip(), (expr, value)


def test_blocking_example_runs_against_the_simulator() -> None:
    """The blocking facade's lines after the async example (issue 26: they opened a serial port no
    machine without hardware has, and the README did not say so)."""
    from topgimbal.sim import BackgroundSimulator

    block = next(b for b in BLOCKS if "topgimbal.Gimbal(" in b)
    code = "import topgimbal\n" + block.split("asyncio.run(main())")[1]
    assert "udp://127.0.0.1:5000" in code and "serial://" not in code.split("#")[0]
    with BackgroundSimulator("C12", seed=4, listen={"udp": [("127.0.0.1", 0)]}) as bg:
        exec(code.replace("udp://127.0.0.1:5000", bg.url), {})  # the README's own code
        target = bg.call(lambda s: (s.gimbal.axis("yaw").target, s.gimbal.axis("pitch").target))
    assert target == (10.0, -20.0)


def test_readme_says_what_the_example_needs() -> None:
    intro = README.split("## From Python", 1)[1].split("```python", 1)[0]
    assert "topgimbal sim --model C12 --udp 127.0.0.1:5000" in intro and "RequestTimeoutError" in intro
