"""The KLV recording: the video copied without re-encoding into MPEG-TS next to an ST 0601 KLV
stream that ffprobe reports (codec klv, KLVA registration) and whose every packet klvdata parses
with the vehicle's position."""

from __future__ import annotations

import asyncio
import json
import math
import subprocess
import threading
from pathlib import Path

import av
import klvdata
import pytest
from pymavlink.dialects.v20 import common as ml

from topgimbal.outputs.klv_record import remux

pytestmark = pytest.mark.external

VALUES = {5: 250.0, 6: 1.0, 7: -2.0, 13: 47.002, 14: 7.998, 15: 650.0, 16: 40.0, 17: 23.0, 18: 20.0, 19: -35.0,
          21: 410.0, 23: 46.999, 24: 8.001, 25: 330.0}  # fmt: skip


def _frame_hashes(path: Path) -> list[str]:
    text = subprocess.run(
        ["ffmpeg", "-loglevel", "error", "-i", str(path), "-map", "0:v", "-f", "framemd5", "-"],
        capture_output=True, check=True, timeout=60, text=True,
    ).stdout  # fmt: skip
    return [line.rsplit(",", 1)[1].strip() for line in text.splitlines() if line and not line.startswith("#")]


def test_ts_with_a_klv_stream_every_packet_parses(source: Path, tmp_path: Path) -> None:
    out = tmp_path / "rec.ts"
    videos, klvs = remux(str(source), out, lambda: VALUES, threading.Event())
    assert videos == 30 and klvs >= 5  # 3 s at 10 fps; KLV at up to 5 Hz, in presentation order
    probe = json.loads(subprocess.run(
        ["ffprobe", "-v", "error", "-show_streams", "-of", "json", str(out)], capture_output=True, check=True, timeout=60
    ).stdout)  # fmt: skip
    kinds = {(s["codec_type"], s["codec_name"], s.get("codec_tag_string")) for s in probe["streams"]}
    assert ("data", "klv", "KLVA") in kinds
    # copied, not re-encoded: every decoded picture identical (framemd5), none lost
    assert _frame_hashes(out) == _frame_hashes(source)
    with av.open(str(out)) as c:
        data = [bytes(p) for p in c.demux(c.streams.data[0]) if p.size]
    assert len(data) == klvs
    for d in data:
        (ls,) = list(klvdata.StreamParser(d))
        values = {item.LDSName: item.value.value for item in ls.items.values() if hasattr(item, "LDSName")}
        assert values["Sensor Latitude"] == pytest.approx(47.002, abs=1e-6)
        assert values["Sensor Longitude"] == pytest.approx(7.998, abs=1e-6)
        assert values["Frame Center Latitude"] == pytest.approx(46.999, abs=1e-6)


def test_nothing_to_say_writes_no_klv_packet(source: Path, tmp_path: Path) -> None:
    videos, klvs = remux(str(source), tmp_path / "quiet.ts", lambda: None, threading.Event())
    assert videos == 30 and klvs == 0


async def test_bridge_records_the_video_with_the_vehicle_position(rig_factory, source: Path, tmp_path: Path) -> None:
    """`mavlink --record DIR` (here the "stream" is a file, re-read after each end as a stream is
    reconnected): a file whose KLV packets all parse with the position the autopilot sends."""
    rec = tmp_path / "rec"
    rig = await rig_factory("SIP", record=str(rec), video_urls=[str(source)])
    autopilot = type(rig.peer)(sysid=1, compid=1)
    await autopilot.connect(rig.bridge.addresses[0][1])

    def klv_packets() -> list[bytes]:
        out: list[bytes] = []
        for f in sorted(rec.glob("*.ts")):
            try:
                with av.open(str(f)) as c:
                    if c.streams.data:
                        out += [bytes(p) for p in c.demux(c.streams.data[0]) if p.size]
            except av.error.FFmpegError:
                pass  # the file being written
        return out

    try:
        for _ in range(40):
            autopilot.send(ml.MAVLink_attitude_message(0, 0.02, -0.01, math.radians(250.0), 0, 0, 0))
            autopilot.send(ml.MAVLink_global_position_int_message(0, 470020000, 79980000, 650000, 350000, 0, 0, 0, 0))
            await asyncio.sleep(0.25)
            if len(klv_packets()) >= 5:
                break
        data = klv_packets()
        assert len(data) >= 5
        for d in data:
            (ls,) = list(klvdata.StreamParser(d))
            values = {item.LDSName: item.value.value for item in ls.items.values() if hasattr(item, "LDSName")}
            assert values["Sensor Latitude"] == pytest.approx(47.002, abs=1e-6)
            assert values["Sensor Longitude"] == pytest.approx(7.998, abs=1e-6)
            assert values["Sensor True Altitude"] == pytest.approx(650.0, abs=0.3)
            assert values["Platform Heading Angle"] == pytest.approx(250.0, abs=0.01)
    finally:
        autopilot.close()
