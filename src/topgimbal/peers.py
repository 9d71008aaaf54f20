"""The one server-side peer table: who a server serves now, bounded, with a lease.

Every server that remote ends can make hold state keeps the same book: the simulator's UDP and
TCP servers, the MAVLink bridge's udpin and tcpin links, the proxy's clients and the RTSP server's
connections. `PeerTable` is that book, written once: peers keyed by address or id, each with the
time it was last heard; a cap with a policy for the newcomer that meets it (`EVICT` the least
recently heard, as a UDP server does so that anyone who talks stays reachable; `REFUSE` the
newcomer, as a TCP server does, whose admitted clients hold a connection it will not cut); a lease
after which an unheard peer expires; forgetting on ICMP "unreachable" or a close; one throttled
log line per refusal or eviction flood; counters for stats.

It does no I/O and reads no clock of its own: times come as `now` arguments or from the injected
`clock` (topgimbal.clock), and what a server must do about a peer that went (close a connection,
drop its streams) it learns through `on_gone`. A shared leaf next to logthrottle.py (which it uses)
rather than in one layer: the simulator, the bridge, the proxy and the video server sit in four
layers, and none of them may import another's.

Order is the book: entries are kept least recently heard first, so eviction takes the first and
expiry stops at the first fresh one (O(1) per datagram on the hot path). That needs the times
given to be non-decreasing, which a monotonic clock gives.
"""

from __future__ import annotations

from collections.abc import Callable, Hashable, Iterator, Mapping
from dataclasses import dataclass
from typing import Generic, Literal, TypeVar

from .clock import MonotonicFn, monotonic
from .logthrottle import ThrottledLog

K = TypeVar("K", bound=Hashable)
V = TypeVar("V")

AtCap = Literal["evict", "refuse"]
EVICT: AtCap = "evict"
REFUSE: AtCap = "refuse"

# Why a peer left the table (`Gone.why`).
EVICTED = "evicted"  # a newcomer needed its place (EVICT policy)
EXPIRED = "expired"  # unheard for the lease
FORGOTTEN = "forgotten"  # the server said so: ICMP unreachable, the connection closed, untrusted


@dataclass(frozen=True)
class Words:
    """A table's two log lines, as `str.format` templates. Fields: `name` (the table's), `count`
    (peers held), `cap`, `newcomer` (the peer knocking); `evicted` also `peer` (the one forgotten)
    and `age_s` (how long it had been unheard)."""

    refused: str = "{name}: {count} peers (the limit); refusing {newcomer}"
    evicted: str = "{name}: {count} peers (the limit): forgetting the least recently heard, {peer} ({age_s:.1f} s ago)"


class Gone(Generic[K, V]):
    """A peer that left the table, why, and when it was last heard. (A plain class with slots: a
    frozen dataclass costs a microsecond to build, on the path of a flood of new peers, and a
    generic NamedTuple needs Python 3.11.)"""

    __slots__ = ("heard_s", "key", "value", "why")

    def __init__(self, key: K, value: V, why: str, heard_s: float) -> None:
        self.key = key
        self.value = value
        self.why = why
        self.heard_s = heard_s

    def __repr__(self) -> str:
        return f"Gone({self.key!r}, {self.why}, heard at {self.heard_s})"


class _Slot(Generic[V]):
    __slots__ = ("heard", "value")

    def __init__(self, value: V, heard: float) -> None:
        self.value = value
        self.heard = heard


class PeerTable(Mapping[K, V], Generic[K, V]):
    """At most `cap` peers, least recently heard first. A read-only Mapping key -> value; change it
    with `admit`, `heard`, `forget`, `expire`, `clear`.

    `at_cap`: EVICT (the least recently heard goes for the newcomer) or REFUSE (the newcomer is
    turned away). `lease_s`: a peer unheard for longer expires (0: never); `expire()` applies it
    (a server calls it from a timer or before it sends), and `make_room()` applies it first when
    the table is full, so a stale peer never keeps a live one out. `on_gone(Gone)` is called for
    every peer evicted, expired or forgotten (after it left the table: the callback may call back
    in), not for `clear()`. `throttle` gets one line per kind (refused, evicted) per its interval,
    in `words`, each peer shown by `describe(key)`."""

    def __init__(
        self,
        cap: int,
        *,
        at_cap: AtCap,
        lease_s: float = 0.0,
        clock: MonotonicFn = monotonic,
        name: str = "peers",
        throttle: ThrottledLog | None = None,
        words: Words = Words(),
        describe: Callable[[K], str] = str,
        on_gone: Callable[[Gone[K, V]], None] | None = None,
    ) -> None:
        if at_cap not in (EVICT, REFUSE):
            raise ValueError(f"at_cap={at_cap!r}: expected {EVICT!r} or {REFUSE!r}")
        if not lease_s >= 0:
            raise ValueError(f"lease_s={lease_s!r}: expected seconds >= 0 (0 = no lease)")
        self.cap = cap  # public: a server may change it (its limit read when a peer arrives)
        self.at_cap = at_cap
        self.lease_s = lease_s
        self.clock = clock
        self.name = name
        self.throttle = throttle
        self.words = words
        self.describe = describe
        self.on_gone = on_gone
        self.refused = 0
        self.evicted = 0
        self.expired = 0
        self.forgotten = 0
        self._slots: dict[K, _Slot[V]] = {}  # least recently heard first

    # -- Mapping ----------------------------------------------------------------------------------

    def __getitem__(self, key: K) -> V:
        return self._slots[key].value

    def __iter__(self) -> Iterator[K]:
        return iter(self._slots)

    def __len__(self) -> int:
        return len(self._slots)

    def __contains__(self, key: object) -> bool:
        return key in self._slots

    def get(self, key: K, default: V | None = None) -> V | None:  # type: ignore[override]
        slot = self._slots.get(key)
        return default if slot is None else slot.value

    def __repr__(self) -> str:
        return f"PeerTable({self.name!r}, {len(self._slots)}/{self.cap}, {self.at_cap})"

    # -- reading ----------------------------------------------------------------------------------

    def heard_at(self, key: K) -> float | None:
        """When `key` was last heard (the table's clock), None when it is not held."""
        slot = self._slots.get(key)
        return None if slot is None else slot.heard

    def oldest(self) -> Gone[K, V] | None:
        """The least recently heard peer (the one EVICT would take), as a Gone not yet gone."""
        for key, slot in self._slots.items():
            return Gone(key, slot.value, "", slot.heard)
        return None

    @property
    def full(self) -> bool:
        return len(self._slots) >= self.cap

    def counts(self) -> dict[str, int]:
        """What the limits did so far, for a server's stats."""
        return {"refused": self.refused, "evicted": self.evicted, "expired": self.expired, "forgotten": self.forgotten}

    # -- changing ---------------------------------------------------------------------------------

    def heard(self, key: K, now: float | None = None) -> V | None:
        """`key` was heard now: its lease renews and it becomes the most recently heard. Its value,
        or None when the table does not hold it (nothing changes then)."""
        slot = self._slots.pop(key, None)
        if slot is None:
            return None
        slot.heard = self.clock() if now is None else now
        self._slots[key] = slot
        return slot.value

    def make_room(self, newcomer: K, now: float | None = None) -> bool:
        """Whether `newcomer` may be admitted now. A peer already held may; otherwise, when the
        table is full, expired peers go first, then the policy: EVICT forgets the least recently
        heard (True), REFUSE counts and logs the refusal (False)."""
        if newcomer in self._slots or len(self._slots) < self.cap:
            return True
        now = self.clock() if now is None else now
        self.expire(now)
        if len(self._slots) < self.cap:
            return True
        if self.at_cap == REFUSE:
            self.refused += 1
            self._log("refused", self.words.refused, newcomer, None, now)
            return False
        key, slot = next(iter(self._slots.items()))  # the least recently heard (full, and cap >= 1)
        self._log("evicted", self.words.evicted, newcomer, (key, slot.heard), now)
        self._remove(key, EVICTED)
        return True

    def admit(self, key: K, value: V, now: float | None = None) -> bool:
        """Hold `value` for `key`, heard now, when there is room (`make_room`); False when refused.
        A key already held gets the new value and is renewed."""
        now = self.clock() if now is None else now
        if not self.make_room(key, now):
            return False
        self._slots.pop(key, None)
        self._slots[key] = _Slot(value, now)
        return True

    def forget(self, key: K, value: V | None = None) -> V | None:
        """The server says `key` is gone (ICMP unreachable, closed): its value, None when not held.
        With `value`, only when that very value is held (a newer peer on the same key stays)."""
        slot = self._slots.get(key)
        if slot is None or (value is not None and slot.value is not value):
            return None
        return self._remove(key, FORGOTTEN).value

    def expire(self, now: float | None = None) -> list[Gone[K, V]]:
        """Every peer unheard for longer than the lease goes (none when lease_s is 0)."""
        if self.lease_s <= 0 or not self._slots:
            return []
        limit = (self.clock() if now is None else now) - self.lease_s
        gone = []
        while self._slots:
            key, slot = next(iter(self._slots.items()))
            if slot.heard >= limit:
                break
            gone.append(self._remove(key, EXPIRED))
        return gone

    def clear(self) -> list[V]:
        """Forget everyone without telling `on_gone` (the server is closing); their values."""
        values = [s.value for s in self._slots.values()]
        self._slots.clear()
        return values

    def _remove(self, key: K, why: str) -> Gone[K, V]:
        slot = self._slots.pop(key)
        if why == EVICTED:
            self.evicted += 1
        elif why == EXPIRED:
            self.expired += 1
        else:
            self.forgotten += 1
        gone = Gone(key, slot.value, why, slot.heard)
        if self.on_gone is not None:
            self.on_gone(gone)
        return gone

    def _log(self, kind: str, template: str, newcomer: K, oldest: tuple[K, float] | None, now: float) -> None:
        throttle = self.throttle
        if throttle is None:
            return
        left_out = throttle.allow(f"peers {kind}")
        if left_out is None:
            return  # counted by the throttle; a flood costs a counter, not a formatted line
        fields: dict[str, object] = {
            "name": self.name, "count": len(self._slots), "cap": self.cap, "newcomer": self.describe(newcomer),
        }  # fmt: skip
        if oldest is not None:
            fields |= {"peer": self.describe(oldest[0]), "age_s": now - oldest[1]}
        line = template.format(**fields)
        if left_out:
            line += throttle.suffix.format(left_out)
        throttle.logger.warning("%s", line)
