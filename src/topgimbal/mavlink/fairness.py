"""How many commands may be in progress at once, in total and per peer (pure: no I/O, no clock).

The bridge runs each command that needs the camera as a task until the camera confirms it. Those
places are bounded (MAX_INFLIGHT in all), and without a per-peer bound one peer sending commands
faster than the camera answers (~1,900/s in the sweep of issue 27) held all of them: every other
ground station's commands were refused TEMPORARILY_REJECTED. So:

- one peer holds at most MAX_INFLIGHT_PER_PEER places;
- the last RESERVED_FOR_IDLE_PEERS places go only to peers that hold none, so several flooding
  peers together still leave a place for a ground station that sends its first command.

A peer is where the message came from on the link (a UDP address, a TCP connection, a serial
port), not the system id a message claims (any peer can claim any id); behind a router every
ground station shares the router's address. Commands that need no camera traffic (the message
interval commands) take no place and are answered whatever the load (commands.py)."""

from __future__ import annotations

from collections.abc import Hashable

MAX_INFLIGHT = 32
MAX_INFLIGHT_PER_PEER = 8
RESERVED_FOR_IDLE_PEERS = 4


class InflightLimits:
    """Places taken per peer; `refusal(peer)` says why a new command cannot start (None: it can)."""

    def __init__(
        self,
        total: int = MAX_INFLIGHT,
        per_peer: int = MAX_INFLIGHT_PER_PEER,
        reserved_for_idle: int = RESERVED_FOR_IDLE_PEERS,
    ) -> None:
        if not 1 <= per_peer <= total or not 0 <= reserved_for_idle < total:
            raise ValueError(f"limits: per_peer {per_peer}, reserved {reserved_for_idle}, total {total}")
        self.total = total
        self.per_peer = per_peer
        self.reserved_for_idle = reserved_for_idle
        self._held: dict[Hashable, int] = {}
        self.in_use = 0

    def held(self, peer: Hashable) -> int:
        return self._held.get(peer, 0)

    def refusal(self, peer: Hashable) -> str | None:
        mine = self.held(peer)
        if self.in_use >= self.total:
            return f"{self.total} commands in progress (the limit)"
        if mine >= self.per_peer:
            return f"this peer has {self.per_peer} commands in progress (the limit per peer)"
        if mine > 0 and self.in_use >= self.total - self.reserved_for_idle:
            return (f"{self.in_use} commands in progress: the last {self.reserved_for_idle} places are kept "
                    "for peers with none")  # fmt: skip
        return None

    def take(self, peer: Hashable) -> None:
        self._held[peer] = self.held(peer) + 1
        self.in_use += 1

    def give_back(self, peer: Hashable) -> None:
        n = self.held(peer)
        if n <= 0:
            return
        if n == 1:
            del self._held[peer]
        else:
            self._held[peer] = n - 1
        self.in_use -= 1


__all__ = ["MAX_INFLIGHT", "MAX_INFLIGHT_PER_PEER", "RESERVED_FOR_IDLE_PEERS", "InflightLimits"]
