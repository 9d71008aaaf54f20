"""Closing in a fixture's teardown what a test made on looptime's virtual clock, on that clock.

looptime runs only the test function on virtual time (its plugin enables the loop's compaction
around the call); a fixture's teardown runs on the same loop with it off, where `loop.time()` is
the real monotonic clock, hours ahead of the virtual one on a machine that has been up for hours.
Everything a test made (a simulator, a bridge, a client) then sees its clock jump by those hours at
the close: the simulator's physics integrated the whole gap in small steps (14 real seconds for a
rig alone on a quiet machine; more than the 60 s close bound beside two busy loops: test_orbit in
fresh-clone runs of `make test`), and link monitors called a live camera silent for 33,147 s.

So a fixture that hands out a maker notes, when the test makes something, whether the test runs on
virtual time (`Made.note()`), and its teardown closes inside `Made.clock()`: the loop's
compaction on again, its time going on from where the test left it."""

from __future__ import annotations

import asyncio
import contextlib
from collections.abc import Iterator


class Made:
    """Whether what a fixture's maker made was made on looptime's virtual clock."""

    def __init__(self) -> None:
        self.virtual = False

    def note(self) -> None:
        """Call in the maker (inside the test): remembers whether the test's loop compacts time."""
        try:
            loop = asyncio.get_running_loop()
        except RuntimeError:  # made outside a loop: nothing on virtual time
            return
        self.virtual = self.virtual or bool(getattr(loop, "looptime_on", False))

    @contextlib.contextmanager
    def clock(self) -> Iterator[None]:
        """Around the teardown's closes: the clock they were made on (no-op for real-time tests)."""
        loop = asyncio.get_running_loop()
        if not self.virtual or getattr(loop, "looptime_on", True):
            yield  # made on real time, or compaction already on (the closes run inside the test)
            return
        with loop.looptime_enabled():  # type: ignore[attr-defined]  # looptime's loop (note() saw it)
            yield
