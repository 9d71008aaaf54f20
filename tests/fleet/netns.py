"""Three "machines" for a test: network namespaces joined by veth pairs, made and always removed by
the test itself (root and iproute2's `ip`). Addresses are private /30s that exist only inside these
namespaces (each has its own stack and no route out), names unique per run.

    cams (10.211.0.1) --veth-- router (10.211.0.2 | 10.211.0.5) --veth-- operator (10.211.0.6)

cams and operator have no route to each other: whatever passes between them goes through the
router's namespace."""

from __future__ import annotations

import os
import secrets
import subprocess
from collections.abc import Iterator
from contextlib import contextmanager
from dataclasses import dataclass

CAMS_IP, ROUTER_CAMS_IP, ROUTER_OP_IP, OP_IP = "10.211.0.1", "10.211.0.2", "10.211.0.5", "10.211.0.6"
IP_TIMEOUT_S = 30.0


class NetnsError(RuntimeError):
    """An `ip` command failed while the namespaces were made."""


def ip(*args: str, ns: str | None = None) -> None:
    argv = ["ip", *(["-n", ns] if ns else []), *args]
    done = subprocess.run(argv, capture_output=True, text=True, timeout=IP_TIMEOUT_S, check=False)
    if done.returncode != 0:
        raise NetnsError(f"{' '.join(argv)}: {done.stderr.strip()}")


@dataclass(frozen=True)
class Machines:
    cams: str
    router: str
    operator: str

    def exec(self, ns: str, *argv: str) -> list[str]:
        """argv run inside namespace `ns` (`ip netns exec` execs it: the same process id)."""
        return ["ip", "netns", "exec", ns, *argv]


@contextmanager
def three_machines() -> Iterator[Machines]:
    tag = f"{os.getpid() % 100000:05d}{secrets.token_hex(2)}"  # ifnames are at most 15 characters
    m = Machines(cams=f"tg{tag}c", router=f"tg{tag}r", operator=f"tg{tag}o")
    made: list[str] = []
    try:
        for ns in (m.cams, m.router, m.operator):
            ip("netns", "add", ns)
            made.append(ns)
            ip("link", "set", "lo", "up", ns=ns)
        ip("link", "add", f"v{tag}c", "netns", m.cams, "type", "veth", "peer", "name", f"v{tag}rc", "netns", m.router)
        ip(
            "link",
            "add",
            f"v{tag}o",
            "netns",
            m.operator,
            "type",
            "veth",
            "peer",
            "name",
            f"v{tag}ro",
            "netns",
            m.router,
        )
        for ns, dev, addr in ((m.cams, f"v{tag}c", CAMS_IP), (m.router, f"v{tag}rc", ROUTER_CAMS_IP),
                              (m.router, f"v{tag}ro", ROUTER_OP_IP), (m.operator, f"v{tag}o", OP_IP)):  # fmt: skip
            ip("addr", "add", f"{addr}/30", "dev", dev, ns=ns)
            ip("link", "set", dev, "up", ns=ns)
        yield m
    finally:
        for ns in reversed(made):  # a namespace's veth ends go with it
            subprocess.run(["ip", "netns", "del", ns], capture_output=True, timeout=IP_TIMEOUT_S, check=False)
