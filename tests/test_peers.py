"""peers.PeerTable, the one server-side peer table (the simulator's UDP and TCP servers, the
bridge's udpin and tcpin links, the proxy's clients, the RTSP server's connections): cap policies,
lease, forgetting, counters and the throttled line, on a fake clock."""

from __future__ import annotations

import logging
from typing import Any

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from topgimbal.clock import FakeClock
from topgimbal.logthrottle import ThrottledLog
from topgimbal.peers import EVICT, EVICTED, EXPIRED, FORGOTTEN, REFUSE, Gone, PeerTable, Words

pytestmark = pytest.mark.virtual


def table(cap: int = 2, at_cap: Any = EVICT, lease_s: float = 0.0, **kw: Any) -> tuple[PeerTable[str, int], list]:
    gone: list[Gone[str, int]] = []
    t: PeerTable[str, int] = PeerTable(cap, at_cap=at_cap, lease_s=lease_s, on_gone=gone.append, **kw)
    return t, gone


def test_evict_forgets_the_least_recently_heard_for_the_newcomer() -> None:
    t, gone = table(cap=2, at_cap=EVICT)
    assert t.admit("a", 1, now=0.0) and t.admit("b", 2, now=1.0)
    assert t.heard("a", now=2.0) == 1  # a is now the most recently heard
    assert t.admit("c", 3, now=3.0)
    assert dict(t) == {"a": 1, "c": 3}
    assert [(g.key, g.value, g.why, g.heard_s) for g in gone] == [("b", 2, EVICTED, 1.0)]
    assert t.counts() == {"refused": 0, "evicted": 1, "expired": 0, "forgotten": 0}
    assert list(t) == ["a", "c"]  # least recently heard first


def test_refuse_turns_the_newcomer_away_and_keeps_everyone() -> None:
    t, gone = table(cap=2, at_cap=REFUSE)
    assert t.admit("a", 1, now=0.0) and t.admit("b", 2, now=1.0)
    assert not t.make_room("c", now=2.0)
    assert not t.admit("c", 3, now=2.0)
    assert dict(t) == {"a": 1, "b": 2} and not gone
    assert t.refused == 2
    # One already held is no newcomer: it is renewed (and may change its value) at the cap.
    assert t.admit("a", 10, now=3.0)
    assert dict(t) == {"b": 2, "a": 10} and t.heard_at("a") == 3.0 and t.refused == 2


def test_heard_renews_only_a_held_peer() -> None:
    t, _ = table()
    assert t.heard("x", now=1.0) is None and "x" not in t and len(t) == 0
    t.admit("x", 7, now=1.0)
    assert t.heard("x", now=4.0) == 7 and t.heard_at("x") == 4.0
    assert t.heard_at("y") is None


def test_the_lease_expires_the_unheard_and_keeps_the_heard() -> None:
    clock = FakeClock()
    t, gone = table(cap=4, lease_s=30.0, clock=clock)
    t.admit("quiet", 1)
    t.admit("chatty", 2)
    clock.advance(20.0)
    t.heard("chatty")
    clock.advance(10.0)  # quiet: exactly 30 s unheard, not longer
    assert t.expire() == [] and len(t) == 2
    clock.advance(0.5)
    [g] = t.expire()
    assert (g.key, g.why, g.heard_s) == ("quiet", EXPIRED, 0.0) and gone == [g]
    assert dict(t) == {"chatty": 2} and t.expired == 1
    assert [g.key for g in t.expire(now=clock() + 1000)] == ["chatty"]


def test_no_lease_never_expires() -> None:
    t, gone = table(lease_s=0.0)
    t.admit("a", 1, now=0.0)
    assert t.expire(now=1e9) == [] and "a" in t and not gone


def test_a_full_table_expires_the_stale_before_its_policy_applies() -> None:
    t, gone = table(cap=2, at_cap=REFUSE, lease_s=30.0)
    t.admit("stale", 1, now=0.0)
    t.admit("live", 2, now=20.0)
    assert not t.admit("new", 3, now=25.0)  # nobody is stale yet: refused
    assert t.admit("new", 3, now=31.0)  # stale is 31 s unheard: it gives its place
    assert dict(t) == {"live": 2, "new": 3}
    assert [(g.key, g.why) for g in gone] == [("stale", EXPIRED)]
    assert t.counts() == {"refused": 1, "evicted": 0, "expired": 1, "forgotten": 0}


def test_forget_removes_and_reports_only_what_is_held() -> None:
    t, gone = table(cap=3)
    first, second = object(), object()
    objs: PeerTable[str, object] = PeerTable(3, at_cap=EVICT, on_gone=gone.append)  # type: ignore[arg-type]
    objs.admit("k", first, now=0.0)
    assert objs.forget("k", second) is None and "k" in objs  # another value on the key: it stays
    assert objs.forget("k", first) is first and "k" not in objs
    assert objs.forget("k") is None and objs.forgotten == 1
    assert [(g.key, g.why) for g in gone] == [("k", FORGOTTEN)]
    t.admit("a", 1, now=0.0)
    assert t.forget("a") == 1 and t.forgotten == 1 and len(t) == 0


def test_on_gone_may_call_back_into_the_table() -> None:
    """A server's callback closes a connection, whose close handler forgets it again: a no-op."""
    t: PeerTable[str, int]
    seen: list[tuple[str, bool]] = []

    def on_gone(g: Gone[str, int]) -> None:
        seen.append((g.key, g.key in t))
        assert t.forget(g.key) is None

    t = PeerTable(1, at_cap=EVICT, lease_s=10.0, on_gone=on_gone)
    t.admit("a", 1, now=0.0)
    t.admit("b", 2, now=1.0)  # a evicted
    t.expire(now=20.0)  # b expired
    assert seen == [("a", False), ("b", False)] and len(t) == 0
    assert t.counts() == {"refused": 0, "evicted": 1, "expired": 1, "forgotten": 0}


def test_clear_tells_nobody() -> None:
    t, gone = table(cap=3)
    t.admit("a", 1, now=0.0)
    t.admit("b", 2, now=0.0)
    assert t.clear() == [1, 2] and len(t) == 0 and not gone and t.counts()["forgotten"] == 0


def test_bad_arguments_are_refused() -> None:
    with pytest.raises(ValueError, match="at_cap"):
        PeerTable(1, at_cap="drop")  # type: ignore[arg-type]
    with pytest.raises(ValueError, match="lease_s"):
        PeerTable(1, at_cap=EVICT, lease_s=-1.0)
    with pytest.raises(ValueError, match="lease_s"):
        PeerTable(1, at_cap=EVICT, lease_s=float("nan"))


def test_refusals_and_evictions_are_logged_once_per_interval(caplog: pytest.LogCaptureFixture) -> None:
    clock = FakeClock()
    logger = logging.getLogger("test.peers")
    throttle = ThrottledLog(logger, 10.0, clock)
    words = Words(
        refused="{name}: {count} of {cap}; refusing {newcomer}",
        evicted="{name}: {count} of {cap}; forgetting {peer} ({age_s:.1f} s ago) for {newcomer}",
    )
    refusing: PeerTable[str, int] = PeerTable(
        1, at_cap=REFUSE, clock=clock, name="r", throttle=throttle, words=words, describe=str.upper
    )
    evicting: PeerTable[str, int] = PeerTable(
        1, at_cap=EVICT, clock=clock, name="e", throttle=throttle, words=words, describe=str.upper
    )
    with caplog.at_level(logging.WARNING, logger="test.peers"):
        refusing.admit("a", 1)
        evicting.admit("a", 1)
        clock.advance(2.5)
        for i in range(5):  # a flood: one line for each kind
            refusing.admit(f"n{i}", i)
            evicting.admit(f"n{i}", i)
        clock.advance(10.0)
        refusing.admit("late", 9)
        evicting.admit("late", 9)
    assert [r.getMessage() for r in caplog.records] == [
        "r: 1 of 1; refusing N0",
        "e: 1 of 1; forgetting A (2.5 s ago) for N0",
        "r: 1 of 1; refusing LATE (4 more like it not logged)",
        "e: 1 of 1; forgetting N4 (10.0 s ago) for LATE (4 more like it not logged)",
    ]
    assert refusing.refused == 6 and evicting.evicted == 6


def test_without_a_throttle_nothing_is_logged(caplog: pytest.LogCaptureFixture) -> None:
    t, _ = table(cap=1, at_cap=REFUSE)
    with caplog.at_level(logging.DEBUG):
        t.admit("a", 1, now=0.0)
        t.admit("b", 2, now=0.0)
    assert t.refused == 1 and not caplog.records


def test_the_mapping_reads_as_a_dict() -> None:
    t, _ = table(cap=3)
    t.admit("a", 1, now=0.0)
    t.admit("b", 2, now=1.0)
    assert t["a"] == 1 and t.get("b") == 2 and t.get("z") is None and t.get("z", 5) == 5
    assert list(t.values()) == [1, 2] and list(t.items()) == [("a", 1), ("b", 2)]
    assert bool(t) and not t.full
    oldest = t.oldest()
    assert oldest is not None and (oldest.key, oldest.heard_s) == ("a", 0.0)
    with pytest.raises(KeyError):
        t["z"]


# -- property: whatever happens, the table stays within its cap and holds no forgotten peer --------

KEYS = st.sampled_from("abcdefgh")
OPS = st.lists(
    st.tuples(st.sampled_from(["admit", "heard", "forget", "expire"]), KEYS, st.floats(0.0, 20.0)),
    max_size=80,
)


@settings(max_examples=300, deadline=None)
@given(
    cap=st.integers(1, 5),
    at_cap=st.sampled_from([EVICT, REFUSE]),
    lease_s=st.sampled_from([0.0, 5.0, 30.0]),
    ops=OPS,
)
def test_the_table_never_passes_its_cap_nor_holds_a_forgotten_peer(
    cap: int, at_cap: Any, lease_s: float, ops: list[tuple[str, str, float]]
) -> None:
    clock = FakeClock()
    gone: list[Gone[str, int]] = []
    t: PeerTable[str, int] = PeerTable(cap, at_cap=at_cap, lease_s=lease_s, clock=clock, on_gone=gone.append)
    model: dict[str, float] = {}  # key -> last heard, what the table should hold, in the order heard
    admitted = 0
    for op, key, dt in ops:
        clock.advance(dt)
        now = clock()
        if op == "admit":
            was_held = key in t
            full_before = len(t) >= cap
            stale = {k for k, h in model.items() if lease_s and now - h > lease_s}
            ok = t.admit(key, ord(key))
            if was_held:
                assert ok
            elif full_before:
                if at_cap == EVICT or stale:
                    assert ok  # EVICT always makes room; a stale peer always gives its place
                    for k in stale:
                        model.pop(k)
                    if len(model) >= cap:  # nobody stale enough: the least recently heard went
                        del model[next(iter(model))]
                else:
                    assert not ok
            else:
                assert ok
            if ok:
                admitted += not was_held
                model.pop(key, None)
                model[key] = now
        elif op == "heard":
            assert (t.heard(key) is not None) == (key in model)
            if key in model:
                del model[key]
                model[key] = now
        elif op == "forget":
            assert (t.forget(key) is not None) == (key in model)
            model.pop(key, None)
            assert key not in t  # a forgotten peer is not held
        else:
            expired = {g.key for g in t.expire()}
            assert expired == {k for k, h in model.items() if lease_s and now - h > lease_s}
            for k in expired:
                del model[k]
        assert len(t) <= cap
        assert list(t) == list(model)  # the same peers, least recently heard first
        assert [t.heard_at(k) for k in t] == list(model.values())
        # Everyone admitted is either held or left once, with a reason that was counted.
        assert admitted == len(t) + len(gone) == len(t) + t.evicted + t.expired + t.forgotten
