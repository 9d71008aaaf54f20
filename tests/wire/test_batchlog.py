"""The proxy's traffic log: the client's JSONL format, written in batches."""

from __future__ import annotations

import json

import pytest

from topgimbal.client.traffic import TrafficLog, read_log
from topgimbal.protocol import decode_any, make_frame
from topgimbal.wire.batchlog import MAX_LINES, BatchedTrafficLog

pytestmark = pytest.mark.loopback


def test_lines_wait_for_flush_and_read_back_as_the_client_writes_them(tmp_path):
    frames = [make_frame("PTZ", "%02X" % (i % 0x15), dst="G") for i in range(3)]
    batched, plain = tmp_path / "batched.jsonl", tmp_path / "plain.jsonl"
    log = BatchedTrafficLog(batched, url="udp://127.0.0.1:5000", model="C12", dialect="skydroid")
    ref = TrafficLog(plain, url="udp://127.0.0.1:5000", model="C12", dialect="skydroid")
    assert len(batched.read_text().splitlines()) == 1  # the header at once
    for f in frames:
        log.record("out", f, decode_any(f))
        ref.record("out", f, decode_any(f))
    assert log.waiting == 3 and len(batched.read_text().splitlines()) == 1
    log.flush()
    assert log.waiting == 0
    ref.close()

    def without_clocks(path):
        return [
            {k: v for k, v in json.loads(x).items() if k not in ("t", "mono")} for x in path.read_text().splitlines()
        ]

    assert without_clocks(batched) == without_clocks(plain)
    assert [r.frame for r in read_log(batched)] == frames
    log.record("in", frames[0], None)
    log.close()  # writes what waits
    assert len(list(read_log(batched))) == 4


@pytest.mark.virtual
def test_a_full_batch_is_written_without_waiting_for_the_timer(tmp_path):
    path = tmp_path / "busy.jsonl"
    log = BatchedTrafficLog(path)
    frame = make_frame("PTZ", "00", dst="G")
    for _ in range(MAX_LINES + 10):
        log.record("out", frame, None)
    assert log.waiting == 10
    assert len(list(read_log(path))) == MAX_LINES
    log.close()
    assert len(list(read_log(path))) == MAX_LINES + 10
