"""The sans-I/O session: matching, late replies, duplicates, retries and ERE, on a fake clock."""

from __future__ import annotations

import pytest

from topgimbal.client.session import Session
from topgimbal.errors import DeviceError, RequestTimeoutError
from topgimbal.protocol import Frame, get_model, make_frame


class FakeClock:
    def __init__(self) -> None:
        self.t = 100.0

    def __call__(self) -> float:
        return self.t


@pytest.fixture
def sky():
    dialect, _model = get_model("C12")
    clock = FakeClock()
    return dialect, Session(dialect, clock=clock, late_window_s=2.0), clock


def reply(dialect, request: Frame, **values):
    return dialect.decode(dialect.response(request, **values))


def test_reply_matches_swapped_addresses_and_same_ident(sky):
    d, s, clock = sky
    req = d.encode("REC", read=True)
    p = s.open(req, timeout_s=1.0, retries=0)
    s.sent(p)
    clock.t += 0.01
    r = s.receive(reply(d, req, state="recording"))
    assert r.matched is p and p.done and p.reply is not None
    assert p.reply.fields == {"state": "recording"}
    assert s.stats.replies == 1 and s.stats.rtt_ms_last == pytest.approx(10.0)


def test_other_ident_or_control_is_not_a_reply(sky):
    d, s, _clock = sky
    req = d.encode("REC", read=True)
    p = s.open(req, timeout_s=1.0, retries=0)
    s.sent(p)
    assert s.receive(reply(d, d.encode("SDC", read=True), remaining_mb=1, total_mb=2)).matched is None
    # a write echo of REC is not the answer to a REC query
    assert s.receive(d.decode(d.encode("REC", action="start").swapped())).matched is None
    assert not p.done


def test_one_outstanding_request_per_key(sky):
    d, s, _ = sky
    s.open(d.encode("REC", read=True), timeout_s=1.0, retries=0)
    with pytest.raises(RuntimeError):
        s.open(d.encode("REC", action="start"), timeout_s=1.0, retries=0)


def test_timeout_then_late_reply_is_dropped_not_given_to_next_request(sky):
    d, s, clock = sky
    req = d.encode("REC", read=True)
    a = s.open(req, timeout_s=0.5, retries=0)
    s.sent(a)
    clock.t += 0.6
    [(p, action)] = s.expire()
    assert p is a and action == "timeout" and isinstance(a.error, RequestTimeoutError)
    b = s.open(req, timeout_s=0.5, retries=0)
    s.sent(b)
    clock.t += 0.1
    late = s.receive(reply(d, req, state="stopped"))  # the answer to `a`, not `b`
    assert late.late and late.matched is None and not b.done
    assert s.stats.late_replies == 1
    fresh = s.receive(reply(d, req, state="recording"))
    assert fresh.matched is b and b.reply.fields == {"state": "recording"}


def test_retry_then_first_attempt_answer_completes_and_second_is_late(sky):
    d, s, clock = sky
    req = d.encode("REC", read=True)
    p = s.open(req, timeout_s=0.5, retries=2)
    s.sent(p)
    clock.t += 0.6
    assert s.expire() == [(p, "retry")]
    s.sent(p)
    assert s.stats.retries == 1
    clock.t += 0.1
    assert s.receive(reply(d, req, state="stopped")).matched is p
    nxt = s.open(req, timeout_s=0.5, retries=0)
    s.sent(nxt)
    clock.t += 0.05
    # the answer to the retry arrives now: it belongs to `p`, not to `nxt`
    assert s.receive(reply(d, req, state="stopped")).late
    assert s.receive(reply(d, req, state="recording")).matched is nxt


def test_lost_attempt_expires_after_late_window(sky):
    d, s, clock = sky
    req = d.encode("REC", read=True)
    a = s.open(req, timeout_s=0.5, retries=0)
    s.sent(a)
    clock.t += 0.6
    s.expire()
    clock.t += 2.0  # beyond the late window: the reply to `a` is presumed lost
    b = s.open(req, timeout_s=0.5, retries=0)
    s.sent(b)
    clock.t += 0.01
    assert s.receive(reply(d, req, state="recording")).matched is b


def test_echo_of_another_set_point_is_stray(sky):
    d, s, _clock = sky
    req = d.encode("GAY", yaw_deg=10.0)
    p = s.open(req, timeout_s=1.0, retries=0)
    s.sent(p)
    other = d.encode("GAY", yaw_deg=20.0).swapped()
    r = s.receive(d.decode(other))
    assert r.stray and not p.done and s.stats.stray_replies == 1
    assert s.receive(d.decode(req.swapped())).matched is p


def test_duplicate_answer_before_a_round_trip_is_dropped(sky):
    d, s, clock = sky
    req = d.encode("REC", read=True)
    a = s.open(req, timeout_s=1.0, retries=0)
    s.sent(a)
    clock.t += 0.0003
    answer = reply(d, req, state="stopped")
    assert s.receive(answer).matched is a
    b = s.open(req, timeout_s=1.0, retries=0)
    s.sent(b)
    clock.t += 0.00001  # far sooner than the 0.3 ms round trip: a copy of the previous answer
    dup = s.receive(answer)
    assert dup.duplicate and not b.done and s.stats.duplicates == 1
    clock.t += 0.0003
    assert s.receive(reply(d, req, state="recording")).matched is b


def test_error_frame_fails_oldest_request_to_that_address(sky):
    d, s, _clock = sky
    req = d.encode("SDC", read=True)
    p = s.open(req, timeout_s=1.0, retries=0)
    s.sent(p)
    other = s.open(d.encode("GAC", read=True), timeout_s=1.0, retries=0)
    s.sent(other)
    ere = make_frame("ERE", b"!!", src="D", dst="U", header="#TP")
    r = s.receive(d.decode(ere))
    assert r.matched is p and isinstance(p.error, DeviceError)
    assert not other.done


def test_fail_all_fails_every_pending_at_once(sky):
    d, s, _ = sky
    ps = [s.open(d.encode(i, read=True), timeout_s=1.0, retries=1) for i in ("GAC", "REC", "SDC")]
    for p in ps:
        s.sent(p)
    failed = s.fail_all(ConnectionError("gone"))
    assert set(failed) == set(ps) and all(isinstance(p.error, ConnectionError) for p in ps)
    assert s.pending == {} and s.next_deadline() is None


def test_fire_and_forget_is_not_pending(sky):
    d, s, _ = sky
    p = s.open(d.encode("GSM", yaw_rate_deg_s=1, pitch_rate_deg_s=0), timeout_s=1.0, retries=3, expect_reply=False)
    s.sent(p)
    assert p.done and s.pending == {} and p.retries == 0


def test_next_deadline_tracks_earliest(sky):
    d, s, clock = sky
    a = s.open(d.encode("GAC", read=True), timeout_s=1.0, retries=0)
    s.sent(a)
    b = s.open(d.encode("REC", read=True), timeout_s=0.2, retries=0)
    s.sent(b)
    assert s.next_deadline() == pytest.approx(clock.t + 0.2)


def test_slow_first_round_trip_does_not_make_fast_answers_duplicates(sky):
    d, s, clock = sky
    req = d.encode("GAC", read=True)
    answer = reply(d, req, yaw_deg=1.0, pitch_deg=0.0, roll_deg=0.0)
    p = s.open(req, timeout_s=1.0, retries=0)
    s.sent(p)
    clock.t += 0.05  # a cold first round trip
    assert s.receive(answer).matched is p
    for _ in range(5):  # then identical answers, each 0.3 ms after its request
        p = s.open(req, timeout_s=1.0, retries=0)
        s.sent(p)
        clock.t += 0.0003
        assert s.receive(answer).matched is p
    assert s.stats.duplicates == 0
