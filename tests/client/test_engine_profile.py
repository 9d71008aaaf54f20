"""The engine does what each model's profile asks, on a fake clock: pacing between commands (C12),
slow answers that block nothing (C12 MOD), echoes of frames sent without waiting, and a request
right after an identical one timed out."""

from __future__ import annotations

import itertools

import pytest

from topgimbal.client.engine import Engine
from topgimbal.client.records import BACKGROUND_MAX_WAIT_S
from topgimbal.errors import RequestTimeoutError
from topgimbal.protocol import get_model

pytestmark = pytest.mark.virtual


class FakeClock:
    def __init__(self) -> None:
        self.t = 100.0

    def __call__(self) -> float:
        return self.t


def engine(model: str = "C12", **kw):
    dialect, profile = get_model(model)
    clock = FakeClock()
    return dialect, Engine(clock=clock, late_window_s=2.0, model=profile, dialect=dialect, **kw), clock


def answer(dialect, request, **values):
    return dialect.decode(dialect.response(request, **values))


def echo(dialect, request):
    return dialect.decode(request.swapped())


def test_c12_frames_go_out_40_ms_apart_whoever_sends_them():
    d, e, clock = engine("C12")
    assert e.pacer.gap_s == 0.04  # from the profile
    a = e.submit(d.encode("GAC", read=True), timeout_s=1.0)
    b = e.submit(d.encode("SDC", read=True), timeout_s=1.0)
    f = e.submit(d.encode("GSM", yaw_rate_deg_s=1, pitch_rate_deg_s=0), timeout_s=1.0, expect_reply=False)
    assert [x.ident for x in e.take_frames()] == ["GAC"]
    assert b.state == f.state == "paced" and e.next_deadline() == pytest.approx(100.04)
    clock.t = 100.03
    e.on_tick()
    assert e.take_frames() == []
    clock.t = 100.04
    e.on_tick()
    assert [x.ident for x in e.take_frames()] == ["SDC"] and b.state == "sent"
    assert b.attempts[0].sent_at == pytest.approx(100.04)  # its timeout runs from when it went out
    clock.t = 100.08
    e.on_tick()
    assert [x.ident for x in e.take_frames()] == ["GSM"] and f.done
    clock.t = 100.081
    e.on_message(answer(d, a.frame, yaw_deg=1, pitch_deg=2, roll_deg=3))
    assert a.done and a.reply is not None


def test_paced_requests_given_up_never_go_out_and_retries_are_paced_too():
    d, e, clock = engine("C12")
    e.submit(d.encode("GAC", read=True), timeout_s=0.1, retries=1)
    b = e.submit(d.encode("SDC", read=True), timeout_s=1.0)
    e.take_frames()
    e.cancel(b)
    clock.t = 100.1
    e.on_tick()  # GAC's retry is due; SDC was dropped while it waited for its turn
    assert [x.ident for x in e.take_frames()] == ["GAC"]
    clock.t = 100.13
    e.submit(d.encode("REC", read=True), timeout_s=1.0)
    assert e.take_frames() == []  # 30 ms after the retry: waits
    clock.t = 100.14
    e.on_tick()
    assert [x.ident for x in e.take_frames()] == ["REC"]


def test_a_waiting_frame_passes_queued_background_feeds():
    """Periodic feeds (position, time, the vehicle's attitude) queue behind the C12's 40 ms gap;
    a photo or any other frame that comes meanwhile goes next, not after them (issue 42: a photo
    behind a queue of feeds waited up to 0.2 s more, 1.8 m of a survey's spacing at 9 m/s)."""
    d, e, clock = engine("C12")
    first = e.submit(d.encode("GAC", read=True), timeout_s=1.0)
    feed = d.encode("GAC", read=True)  # three of a feed, queued (identical: none supersedes another)
    feeds = [e.submit(feed, timeout_s=1.0, expect_reply=False, background=True) for _ in range(3)]
    photo = e.submit(d.encode("REC", read=True), timeout_s=1.0)
    assert [x.ident for x in e.take_frames()] == ["GAC"] and first.state == "sent"
    assert photo.state == "paced" and all(f.state == "paced" for f in feeds)
    clock.t = 100.04
    e.on_tick()
    assert [x.ident for x in e.take_frames()] == ["REC"] and photo.state == "sent"
    for k in range(3):  # then the feeds, in their order, 40 ms apart
        clock.t = 100.08 + 0.04 * k
        e.on_tick()
        assert [x.ident for x in e.take_frames()] == ["GAC"] and feeds[k].done
    assert all(f.done for f in feeds)


def test_a_feed_is_let_pass_for_a_bounded_time_by_a_loop_that_always_has_a_frame_waiting():
    """A pointing loop that queues its next set-point before every turn took every turn: the
    vehicle attitude feed (FAI, 10 Hz) never went, and under ArduPilot SITL the C12 held a
    vehicle attitude 10 s old. A feed now waits BACKGROUND_MAX_WAIT_S at most, then goes; never
    two such in a row, so the loop keeps most turns; and what goes is the newest feed value."""
    d, e, clock = engine("C12")
    gap = e.pacer.gap_s
    sent: list[tuple[float, str, bytes]] = []
    fed: list[tuple[float, bytes]] = []  # every FAI submitted (the feed's values at that time)
    step = 0
    while clock.t < 103.0:
        if step % 10 == 0:  # the feed: 10 Hz, a new value each time (it supersedes the one waiting)
            fai = d.encode("FAI", yaw_deg=0.0, pitch_deg=0.01 * step, roll_deg=0.0)
            fed.append((clock.t, fai.data))
            e.submit(fai, timeout_s=1.0, expect_reply=False, background=True)
        if not any(tx.frame.ident == "GSM" and tx.state == "paced" for tx in e.pacer.queue):
            # the loop: a new rate set-point whenever none waits (a distinct one each time)
            e.submit(d.encode("GSM", yaw_rate_deg_s=(step % 50) / 10, pitch_rate_deg_s=0), timeout_s=1.0,
                     expect_reply=False)  # fmt: skip
        e.on_tick()
        sent += [(clock.t, f.ident, f.data) for f in e.take_frames()]
        clock.t = round(clock.t + 0.01, 6)
        step += 1
    idents = [i for _, i, _ in sent]
    fai_at = [t for t, i, _ in sent if i == "FAI"]
    assert len(fai_at) >= 8, idents  # 3 s: one at least every BACKGROUND_MAX_WAIT_S + two turns
    assert max(b - a for a, b in itertools.pairwise(fai_at)) <= BACKGROUND_MAX_WAIT_S + 0.1 + 2 * gap + 1e-9
    assert all(not (a == b == "FAI") for a, b in itertools.pairwise(idents))  # never two in a row
    assert idents.count("GSM") >= 3 * idents.count("FAI")  # the loop keeps most turns
    for t, ident, data in sent:  # each FAI that went carries the newest value fed before it went
        if ident == "FAI":
            assert data == [v for at, v in fed if at <= t][-1]
    times = [t for t, _, _ in sent]
    assert all(b - a >= gap - 1e-9 for a, b in itertools.pairwise(times))  # and still 40 ms apart


def test_pacing_can_be_turned_off_and_other_models_have_none():
    d, e, _ = engine("C12", min_gap_s=0)
    for ident in ("GAC", "SDC", "REC"):
        e.submit(d.encode(ident, read=True), timeout_s=1.0)
    assert len(e.take_frames()) == 3
    d, e, _ = engine("C10")
    for ident in ("GAC", "VER", "REC"):
        e.submit(d.encode(ident, read=True), timeout_s=1.0)
    assert len(e.take_frames()) == 3


def test_a_slow_query_is_not_retried_nor_deferred_and_its_late_answer_is_dispatched():
    d, e, clock = engine("C12", min_gap_s=0)
    mod = d.encode("MOD", read=True)
    a = e.submit(mod, timeout_s=0.5, retries=2, slow=True)
    assert a.retries == 0
    clock.t += 0.5
    e.on_tick()
    assert isinstance(a.error, RequestTimeoutError) and "very late or never" in str(a.error)
    b = e.submit(mod, timeout_s=0.5, slow=True)  # not deferred behind a's open attempt
    assert b.state == "sent" and len(e.take_frames()) == 2
    other = e.submit(d.encode("GAC", read=True), timeout_s=0.5)
    assert other.state == "sent"  # nothing else waits for MOD
    clock.t += 0.1
    got = e.on_message(answer(d, mod, model="C12"))
    assert got.kind == "answer" and got.tx is b  # any answer to a constant is right
    clock.t += 120.0  # minutes later, the first attempt's answer
    late = e.on_message(answer(d, mod, model="C12"))
    assert late.dispatch  # reaches the state cache and subscribers


def test_echoes_of_frames_sent_without_waiting_are_not_late_replies():
    d, e, clock = engine("C13")
    stop = d.encode("PTZ", action="stop")
    for _ in range(3):
        e.submit(stop, timeout_s=0.5, expect_reply=False)
    clock.t += 0.01
    assert e.on_message(echo(d, stop)).kind == "unawaited"
    assert e.stats.late_replies == 0


def test_a_write_after_unechoed_writes_of_other_data_is_not_held_back():
    d, e, clock = engine("C13")
    for _ in range(3):
        e.submit(d.encode("PTZ", action="stop"), timeout_s=0.5, expect_reply=False)
    e.take_frames()
    nudge = d.encode("PTZ", action="up")
    assert not d.command("PTZ").is_idempotent(nudge)  # a step: sent once, on a quiet key
    tx = e.submit(nudge, timeout_s=0.5, exclusive=True)
    clock.t += 0.06  # quiet for the copy window
    e.on_tick()
    assert tx.state == "sent"  # the stops' open attempts carry other data: no 2 s wait


def test_an_identical_write_right_after_a_timeout_takes_its_echo():
    d, e, clock = engine("C12", min_gap_s=0)
    gam = d.encode("GAM", yaw_deg=10, pitch_deg=-5)
    first = e.submit(gam, timeout_s=0.2, retries=2)
    for _ in range(3):
        clock.t += 0.2
        e.on_tick()
    assert isinstance(first.error, RequestTimeoutError)
    second = e.submit(gam, timeout_s=0.2, retries=2)  # within the 2 s late window
    assert second.state == "sent"
    clock.t += 0.01
    got = e.on_message(echo(d, gam))
    assert got.kind == "answer" and got.tx is second and second.error is None
    assert e.stats.late_replies == 0


def test_an_identical_read_right_after_a_timeout_is_answered_not_failed():
    d, e, clock = engine("C12", min_gap_s=0)
    gac = d.encode("GAC", read=True)
    first = e.submit(gac, timeout_s=0.2, retries=0)
    clock.t += 0.2
    e.on_tick()
    assert isinstance(first.error, RequestTimeoutError)
    second = e.submit(gac, timeout_s=0.2, retries=0)
    assert second.state == "deferred"  # the first may still be answered: its answer is not ours
    clock.t += 0.05
    late = e.on_message(answer(d, gac, yaw_deg=1, pitch_deg=1, roll_deg=0))
    assert late.kind == "late" and second.state == "sent"  # that answer closed it: ours goes out now
    clock.t += 0.01
    got = e.on_message(answer(d, gac, yaw_deg=2, pitch_deg=2, roll_deg=0))
    assert got.tx is second and second.reply.fields["yaw_deg"] == 2
