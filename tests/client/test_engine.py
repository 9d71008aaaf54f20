"""The transaction engine, case by case, on a fake clock: matching, late answers, deferral,
retries, echoes, duplicates, ERE and recovered frames."""

from __future__ import annotations

import pytest

from topgimbal.client.engine import Engine
from topgimbal.errors import DeviceError, RequestTimeoutError
from topgimbal.protocol import Frame, get_model, make_frame

pytestmark = pytest.mark.virtual


class FakeClock:
    def __init__(self) -> None:
        self.t = 100.0

    def __call__(self) -> float:
        return self.t


@pytest.fixture
def sky():
    dialect, model = get_model("C12")
    clock = FakeClock()
    return (
        dialect,
        Engine(clock=clock, late_window_s=2.0, dup_window_s=0.05, model=model, dialect=dialect, min_gap_s=0),
        clock,
    )


def answer(dialect, request: Frame, **values):
    return dialect.decode(dialect.response(request, **values))


def echo(dialect, request: Frame):
    return dialect.decode(request.swapped())


def sent(engine) -> list[Frame]:
    return engine.take_frames()


def test_answer_has_the_identifier_control_and_swapped_addresses(sky):
    d, e, clock = sky
    req = d.encode("REC", read=True)
    tx = e.submit(req, timeout_s=1.0, retries=0)
    assert sent(e) == [req]
    clock.t += 0.01
    assert e.on_message(answer(d, d.encode("SDC", read=True), remaining_mb=1, total_mb=2)).tx is None
    assert e.on_message(echo(d, d.encode("REC", action="start"))).tx is None  # a write echo is not the answer
    r = e.on_message(answer(d, req, state="recording"))
    assert r.kind == "answer" and r.tx is tx and tx.reply.fields == {"state": "recording"}
    assert e.stats.replies == 1 and e.stats.rtt_ms_last == pytest.approx(10.0)
    assert e.take_finished() == [tx]


def test_requests_on_one_key_wait_their_turn(sky):
    d, e, clock = sky
    a = e.submit(d.encode("REC", read=True), timeout_s=1.0)
    b = e.submit(d.encode("REC", action="start"), timeout_s=1.0)  # same (REC, D): queued, not an error
    assert len(sent(e)) == 1 and b.state == "queued"
    clock.t += 0.01
    e.on_message(answer(d, a.frame, state="stopped"))
    assert a.done and b.state == "sent" and sent(e) == [b.frame]


def timed_out_read(d, e, clock) -> Frame:
    """A REC query sent and timed out (no retry) 0.6 s ago: the query, for the next one."""
    req = d.encode("REC", read=True)
    a = e.submit(req, timeout_s=0.5, retries=0)
    clock.t += 0.6
    e.on_tick()
    assert isinstance(a.error, RequestTimeoutError)
    return req


def test_a_late_answer_never_completes_the_next_read(sky):
    d, e, clock = sky
    req = timed_out_read(d, e, clock)
    b = e.submit(req, timeout_s=0.5, retries=0)
    assert b.state == "deferred" and sent(e) == [req]  # only `a` went out: `a` may still be answered
    clock.t += 0.1
    late = e.on_message(answer(d, req, state="stopped"))  # `a`'s answer
    assert late.kind == "late" and not b.done and e.stats.late_replies == 1
    assert b.state == "sent"  # that answer closed `a`: now `b` goes out
    clock.t += 0.01
    assert e.on_message(answer(d, req, state="recording")).tx is b and b.reply.fields == {"state": "recording"}


def test_an_answer_to_any_attempt_of_the_live_request_counts(sky):
    d, e, clock = sky
    req = d.encode("REC", read=True)
    p = e.submit(req, timeout_s=0.3, retries=2)
    clock.t += 0.3
    e.on_tick()  # retry
    assert e.stats.retries == 1 and len(sent(e)) == 2
    clock.t += 0.1  # the first attempt's answer, 0.4 s late
    assert e.on_message(answer(d, req, state="stopped")).tx is p


def test_a_read_waits_at_most_the_late_window_for_earlier_attempts(sky):
    d, e, clock = sky
    req = d.encode("REC", read=True)
    e.submit(req, timeout_s=0.5, retries=0)
    clock.t += 0.6
    e.on_tick()
    b = e.submit(req, timeout_s=0.5, retries=0)
    assert b.state == "deferred" and e.next_deadline() == pytest.approx(100.0 + 2.0)
    clock.t = 102.0
    e.on_tick()
    assert b.state == "sent" and e.stats.deferred == 1
    clock.t += 0.6
    e.on_tick()
    assert "waited 1.40 s" in str(b.error) and "2.00 s in all" in str(b.error)


def test_a_write_needs_an_echo_carrying_its_data(sky):
    d, e, clock = sky
    req = d.encode("GAY", yaw_deg=10.0)
    tx = e.submit(req, timeout_s=1.0, retries=0)
    clock.t += 0.01
    r = e.on_message(echo(d, d.encode("GAY", yaw_deg=20.0)))  # no attempt sent 20 degrees
    assert r.kind == "mismatch" and isinstance(tx.error, DeviceError) and "GAY" in str(tx.error)


@pytest.mark.parametrize("write", [True, False])
def test_an_answer_read_after_the_process_stood_still_answers_its_request(sky, write):
    """A process that stood still longer than the late window (a loaded host: 2 s without the
    CPU) reads the answer before its overdue timers run. The request's own attempt is still its
    own: the answer is taken. (Forgotten as too old, a write's echo that carried the data sent
    was reported as "does not carry the data sent", a DeviceError the device never earned.)"""
    d, e, clock = sky
    req = d.encode("GAY", yaw_deg=10.0) if write else d.encode("REC", read=True)
    tx = e.submit(req, timeout_s=0.5, retries=2)
    assert sent(e) == [req]
    clock.t += 2.5  # no timer ran meanwhile: the answer is read first
    r = e.on_message(echo(d, req) if write else answer(d, req, state="stopped"))
    assert r.kind == "answer" and r.tx is tx and tx.error is None and tx.reply is not None
    assert e.stats.errors == 0 and e.take_finished() == [tx]


def test_an_echo_with_other_data_after_a_stall_is_still_a_mismatch(sky):
    d, e, clock = sky
    tx = e.submit(d.encode("GAY", yaw_deg=10.0), timeout_s=0.5, retries=2)
    sent(e)
    clock.t += 2.5
    r = e.on_message(echo(d, d.encode("GAY", yaw_deg=20.0)))
    assert r.kind == "mismatch" and isinstance(tx.error, DeviceError)


def test_a_finished_request_s_attempts_are_forgotten_after_the_late_window(sky):
    """Only a request still waiting keeps its attempts past the window: once it timed out they go,
    and a read on the key is no longer deferred for them."""
    d, e, clock = sky
    req = timed_out_read(d, e, clock)
    clock.t += 2.0
    b = e.submit(req, timeout_s=0.5, retries=0)
    assert b.state == "sent"
    clock.t += 0.01
    assert e.on_message(answer(d, req, state="stopped")).tx is b


def test_an_echo_cut_short_is_no_acknowledgement(sky):
    d, e, _clock = sky
    req = d.encode("IPV", address="192.168.144.108")
    tx = e.submit(req, timeout_s=1.0, retries=0)
    short = req.swapped(data=req.data[:-1])  # decodes fine, other length
    e.on_message(d.decode(short))
    assert isinstance(tx.error, DeviceError) and short.text() in str(tx.error)


def test_an_earlier_write_s_echo_is_late_not_an_error(sky):
    d, e, clock = sky
    old = e.submit(d.encode("GAY", yaw_deg=20.0), timeout_s=0.2, retries=0)
    clock.t += 0.3
    e.on_tick()
    assert old.error is not None
    tx = e.submit(d.encode("GAY", yaw_deg=10.0), timeout_s=1.0, retries=0)
    assert tx.state == "sent"  # writes are not deferred: an echo says which data it carries
    assert e.on_message(echo(d, old.frame)).kind == "late" and not tx.done
    assert e.on_message(echo(d, tx.frame)).tx is tx and tx.error is None


def test_a_photo_goes_out_once_on_a_quiet_key(sky):
    d, e, clock = sky
    cap = d.encode("CAP")
    a = e.submit(cap, timeout_s=0.2, retries=3, exclusive=True)
    assert a.retries == 0 and a.timeout_s == pytest.approx(0.8)  # as long in all as 4 attempts
    clock.t += 0.9
    e.on_tick()
    assert "never retried" in str(a.error) and len(sent(e)) == 1
    b = e.submit(cap, timeout_s=0.2, exclusive=True)
    assert b.state == "deferred"  # `a`'s acknowledgement may still come: it must not pass for `b`'s
    clock.t += 0.2
    assert e.on_message(echo(d, cap)).kind == "late" and b.state == "deferred"  # a copy may follow
    clock.t += 0.05
    e.on_tick()
    assert b.state == "sent"
    clock.t += 0.01
    assert e.on_message(echo(d, cap)).tx is b


def test_a_copy_of_the_previous_answer_sooner_than_a_round_trip_is_dropped(sky):
    d, e, clock = sky
    req = d.encode("REC", read=True)
    a = e.submit(req, timeout_s=1.0)
    clock.t += 0.0003
    ans = answer(d, req, state="stopped")
    assert e.on_message(ans).tx is a
    b = e.submit(req, timeout_s=1.0)
    clock.t += 0.00001
    dup = e.on_message(ans)
    assert dup.kind == "duplicate" and not dup.dispatch and not b.done and e.stats.duplicates == 1
    clock.t += 0.0003
    assert e.on_message(answer(d, req, state="recording")).tx is b


def test_a_slow_first_round_trip_does_not_make_fast_answers_duplicates(sky):
    d, e, clock = sky
    req = d.encode("GAC", read=True)
    ans = answer(d, req, yaw_deg=1.0, pitch_deg=0.0, roll_deg=0.0)
    p = e.submit(req, timeout_s=1.0)
    clock.t += 0.05
    assert e.on_message(ans).tx is p
    for _ in range(5):
        p = e.submit(req, timeout_s=1.0)
        clock.t += 0.0003
        assert e.on_message(ans).tx is p
    assert e.stats.duplicates == 0


def exchange(engine, clock, req: Frame, ans, rtts_s) -> None:
    """Queries of `req`, each answered with `ans` after its round trip."""
    for rtt in rtts_s:
        p = engine.submit(req, timeout_s=1.0)
        clock.t += rtt
        assert engine.on_message(ans).tx is p


def test_a_fast_answer_after_slow_first_round_trips_is_taken(sky):
    # Seen on loopback under load: round trips of 0.24 and 0.36 ms, then a real answer 0.1 ms
    # after its query. Half the fastest of two samples (0.12 ms) took it for a copy; until the
    # round trips settle a quarter of it bounds how fast an answer can be.
    d, e, clock = sky
    req = d.encode("GAC", read=True)
    exchange(e, clock, req, answer(d, req, yaw_deg=1.0, pitch_deg=0.0, roll_deg=0.0), (0.00024, 0.00036, 0.0001))
    assert e.stats.duplicates == 0 and not e.copies_seen


def test_a_suspected_copy_that_nothing_follows_does_not_mark_the_link(sky):
    d, e, clock = sky
    req = d.encode("GAC", read=True)
    ans = answer(d, req, yaw_deg=1.0, pitch_deg=0.0, roll_deg=0.0)
    exchange(e, clock, req, ans, (0.001,) * 3)
    p = e.submit(req, timeout_s=0.5, retries=1)
    assert len(sent(e)) == 4
    clock.t += 0.00005  # sooner than a quarter of the fastest round trip: suspected
    assert e.on_message(ans).kind == "duplicate" and not p.done
    clock.t += 0.5
    e.on_tick()
    assert len(sent(e)) == 1 and p.state == "sent"  # retried
    clock.t += 0.001
    assert e.on_message(ans).tx is p
    assert not e.copies_seen  # the suspect was this request's answer: the link copies nothing
    # reads are held back only while the retried attempt may still be answered, never by the
    # copy wait (the duplicate window) afterwards
    clock.t += 2.5
    exchange(e, clock, req, ans, (0.001,) * 3)
    assert e.stats.deferred == 0


def test_a_suspected_copy_followed_by_the_answer_marks_the_link(sky):
    d, e, clock = sky
    req = d.encode("GAC", read=True)
    old = answer(d, req, yaw_deg=1.0, pitch_deg=0.0, roll_deg=0.0)
    exchange(e, clock, req, old, (0.001,) * 3)
    p = e.submit(req, timeout_s=1.0)
    clock.t += 0.00005
    assert e.on_message(old).kind == "duplicate"
    clock.t += 0.001
    new = answer(d, req, yaw_deg=2.0, pitch_deg=0.0, roll_deg=0.0)
    assert e.on_message(new).tx is p and p.reply is not None and p.reply.fields["yaw_deg"] == 2.0
    assert e.copies_seen  # from now on a read waits until a copy of the last answer would have come
    q = e.submit(req, timeout_s=1.0)
    assert q.state == "deferred"


def test_ere_fails_the_only_request_that_it_can_answer(sky):
    d, e, _clock = sky
    p = e.submit(d.encode("SDC", read=True), timeout_s=1.0)
    ere = d.decode(make_frame("ERE", b"!!", src="D", dst="U", header="#TP"))
    r = e.on_message(ere)
    assert r.tx is p and isinstance(p.error, DeviceError) and "ERE" in str(p.error)


def test_ere_with_two_candidates_fails_neither_but_is_mentioned(sky):
    d, e, clock = sky
    a = e.submit(d.encode("SDC", read=True), timeout_s=0.5)
    b = e.submit(d.encode("REC", read=True), timeout_s=0.5)
    e.on_message(d.decode(make_frame("ERE", b"!!", src="D", dst="U", header="#TP")))
    assert not a.done and not b.done
    clock.t += 0.6
    e.on_tick()
    assert "may answer this request or another" in str(a.error)


def test_fail_all_ends_everything_at_once(sky):
    d, e, _ = sky
    txs = [e.submit(d.encode(i, read=True), timeout_s=1.0, retries=1) for i in ("GAC", "REC", "SDC", "GAC")]
    failed = e.fail_all(ConnectionError("gone"))
    assert set(failed) == set(txs) and all(isinstance(t.error, ConnectionError) for t in txs)
    assert e.live == {} and e.next_deadline() is None


def test_fire_and_forget_is_not_live(sky):
    d, e, _ = sky
    p = e.submit(d.encode("GSM", yaw_rate_deg_s=1, pitch_rate_deg_s=0), timeout_s=1.0, retries=3, expect_reply=False)
    assert p.done and e.live == {} and p.retries == 0 and len(sent(e)) == 1


def test_recovered_frames_answer_only_where_firmware_is_known_to_err(sky):
    d, e, clock = sky
    req = d.encode("IPV", read=True)
    tx = e.submit(req, timeout_s=1.0)
    cut = d.response(req, address="10.0.0.1")
    cut = cut._replace(data=cut.data[:-1], declared_length=len(cut.data))  # a truncated frame, "recovered"
    assert e.on_message(d.decode(cut)).kind == "ignored" and not tx.done
    ver = d.encode("VER", read=True)
    vtx = e.submit(ver, timeout_s=1.0)
    quirky = d.response(ver, version="1.5.2")._replace(declared_length=3)  # the real C12's VER answer
    clock.t += 0.01
    assert e.on_message(d.decode(quirky)).tx is vtx


def test_topotek_rec_and_cap_are_acknowledged_by_their_feedback():
    d, model = get_model("SIP")
    clock = FakeClock()
    e = Engine(clock=clock, model=model, dialect=d)
    rec = d.encode("REC", action="start", src="P")
    tx = e.submit(rec, timeout_s=1.0, fields={"action": "start"})
    stopped = d.notification("REC", src="D", dst="P", state="stopped", file_index=3)
    assert e.on_message(d.decode(stopped)).tx is None  # feedback, but not of a start
    started = d.notification("REC", src="D", dst="P", state="started", file_index=4)
    assert e.on_message(d.decode(started)).tx is tx
    cap = e.submit(d.encode("CAP", src="P"), timeout_s=1.0, exclusive=True, fields={"mode": "visible_thermal"})
    clock.t += 0.1
    taken = d.notification("CAP", src="D", dst="P", state="taken", file_index=9)
    assert e.on_message(d.decode(taken)).tx is cap


def test_on_a_streaming_key_samples_are_not_copies_and_answer_the_read_at_once(sky):
    """An attitude stream (C12 GAC at 50 Hz, identical frames while the gimbal is still) sends
    frames on the attitude query's key: they were taken for copies of the last answer, which
    marked the link as copying, and every later read waited for a quiet key that never came."""
    d, e, clock = sky
    req = d.encode("GAC", read=True)
    sample = answer(d, req, yaw_deg=0.0, pitch_deg=0.0, roll_deg=0.0)
    e.set_stream("GAC", True)
    for _ in range(5):  # a read while the stream runs: sent at once, answered by the next sample
        clock.t += 0.02
        assert e.on_message(sample).kind == "unsolicited"
        tx = e.submit(req, timeout_s=1.0, retries=2)
        assert tx.state == "sent" and sent(e) == [req]
        clock.t += 0.005
        r = e.on_message(sample)
        assert r.kind == "answer" and r.tx is tx and tx.reply is sample
        clock.t += 0.005
        assert e.on_message(sample).kind == "unsolicited"  # the next sample: nobody's copy
    assert not e.copies_seen and e.stats.duplicates == 0 and e.stats.deferred == 0
    assert e.stats.late_replies == 0 and e.stats.stray_replies == 0 and e.stats.rtt_ms_min is None


def test_without_the_stream_flag_the_same_frames_still_mark_copies(sky):
    """The rule above is the stream's alone: off (and a late window after), copies are copies."""
    d, e, clock = sky
    req = d.encode("GAC", read=True)
    sample = answer(d, req, yaw_deg=0.0, pitch_deg=0.0, roll_deg=0.0)
    e.set_stream("GAC", True)
    e.set_stream("GAC", False)  # its frames may still come for the late window
    tx = e.submit(req, timeout_s=1.0, retries=0)
    clock.t += 0.005
    assert e.on_message(sample).tx is tx and sent(e) == [req]
    clock.t += 0.01
    assert e.on_message(sample).kind == "unsolicited" and not e.copies_seen
    clock.t += 2.5  # the late window is over: the stream's rule no longer applies
    tx = e.submit(req, timeout_s=1.0, retries=0)
    clock.t += 0.005
    assert e.on_message(sample).tx is tx
    clock.t += 0.01
    assert e.on_message(sample).kind == "late" and e.copies_seen  # a repeat of an answer taken
