"""Issue 43.6: a recording never fails silently. A full disk, a vanished folder and a bad
`--record` path are WARNINGs or exit 2 with the file kept; no empty file is left behind; two
recorders in one folder never write one file name."""

from __future__ import annotations

import logging
import os
import subprocess
import sys
import threading
from pathlib import Path

import pytest

from topgimbal.mavlink import klv_record
from topgimbal.outputs.klv_record import Recorder, RecordWriteError, remux
from waiting import until_blocking

pytestmark = pytest.mark.external  # ffmpeg makes the source


def test_a_write_error_is_raised_not_swallowed(source: Path) -> None:
    with pytest.raises(RecordWriteError, match="No space left on device"):
        remux(str(source), Path("/dev/full"), lambda: None, threading.Event())


def test_a_full_disk_is_a_warning_each_time_and_leaves_no_empty_file(
    source: Path, tmp_path: Path, monkeypatch: pytest.MonkeyPatch, caplog: pytest.LogCaptureFixture
) -> None:
    real_reserve = klv_record.reserve

    def full_disk(directory: Path, stamp: str) -> Path:  # every new file lands on a full device
        dst = real_reserve(directory, stamp)
        dst.unlink()
        dst.symlink_to("/dev/full")
        return dst

    monkeypatch.setattr(klv_record, "reserve", full_disk)
    monkeypatch.setattr(klv_record, "RETRY_S", 0.05)
    monkeypatch.setattr(klv_record, "RETRY_MAX_S", 0.2)
    rec = Recorder(str(source), tmp_path / "rec", lambda: None)
    with caplog.at_level(logging.INFO, logger="topgimbal.mavlink"):
        rec.start()
        try:
            until_blocking("four write failures", lambda: rec.write_failures >= 4, bound_s=30)
        finally:
            rec.close()
    warnings = [r.getMessage() for r in caplog.records if r.levelno == logging.WARNING]
    assert len(warnings) >= 4 and all("No space left on device" in w for w in warnings), warnings
    assert "nothing written (no empty file left)" in warnings[0] and "trying a new file in 0.2 s" in warnings[-1]
    assert list((tmp_path / "rec").iterdir()) == []  # not one empty .ts


def test_a_file_cut_short_is_kept_and_said(source: Path, tmp_path: Path) -> None:
    """A file size limit (what a filling disk does to one file): the part written stays, playable."""
    script = (
        "import logging, resource, signal, sys, time\n"
        "signal.signal(signal.SIGXFSZ, signal.SIG_IGN)\n"
        "from topgimbal.mavlink import klv_record\n"
        "logging.basicConfig(level=logging.WARNING, format='%(levelname)s %(message)s')\n"
        "resource.setrlimit(resource.RLIMIT_FSIZE, (20000, 20000))\n"
        "rec = klv_record.Recorder(sys.argv[1], sys.argv[2], lambda: None)\n"
        "rec.start()\n"
        "while rec.write_failures < 1: time.sleep(0.05)\n"
        "rec.close()\n"
    )
    out = subprocess.run([sys.executable, "-c", script, str(source), str(tmp_path / "rec")], capture_output=True,
                         text=True, timeout=120)  # fmt: skip
    assert out.returncode == 0, out.stderr
    assert "WARNING recording" in out.stderr and "File too large" in out.stderr and "kept (" in out.stderr
    files = sorted((tmp_path / "rec").glob("*.ts"))
    assert files and all(f.stat().st_size > 0 for f in files)
    frames = subprocess.run(["ffprobe", "-v", "error", "-count_frames", "-select_streams", "v:0", "-show_entries",
                             "stream=nb_read_frames", "-of", "csv=p=0", str(files[0])],
                            capture_output=True, text=True, timeout=60).stdout  # fmt: skip
    assert int(frames.split()[0].rstrip(",")) > 0, frames


def test_two_recorders_in_one_folder_in_one_second_write_two_files(
    source: Path, tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.setattr(klv_record, "wall_time", lambda: 1_800_000_000.0)  # the same second for both
    a, b = (Recorder(str(source), tmp_path, lambda: None) for _ in range(2))
    a.start()
    b.start()
    try:
        until_blocking("a file each", lambda: a.files and b.files, bound_s=30)
    finally:
        a.close()
        b.close()
    assert not set(a.files) & set(b.files), (a.files, b.files)


def test_a_vanished_folder_is_said_and_made_again(
    source: Path, tmp_path: Path, monkeypatch: pytest.MonkeyPatch, caplog: pytest.LogCaptureFixture
) -> None:
    monkeypatch.setattr(klv_record, "RETRY_S", 0.05)
    folder = tmp_path / "rec"
    rec = Recorder(str(source), folder, lambda: None)
    with caplog.at_level(logging.WARNING, logger="topgimbal.mavlink"):
        rec.start()
        try:
            until_blocking("a first file", lambda: len(rec.files) >= 1, bound_s=30)
            # moved away in one step: rmtree raced the recorder making its next file (ENOTEMPTY)
            folder.rename(tmp_path / "moved-away")
            until_blocking(
                "a file in the folder made again", lambda: folder.is_dir() and any(folder.glob("*.ts")), bound_s=30
            )
        finally:
            rec.close()
    assert f"the folder {folder} is gone: making it again" in caplog.text


@pytest.mark.parametrize("bad", ["file", "/proc/topgimbal-nowhere/rec"])
def test_a_bad_record_path_is_exit_2_in_one_line(tmp_path: Path, bad: str) -> None:
    path = tmp_path / "a-file" if bad == "file" else Path(bad)
    if bad == "file":
        path.write_text("")
    out = subprocess.run([sys.executable, "-m", "topgimbal.cli.main", "mavlink", "--url", "udp://127.0.0.1:9",
                          "--model", "C12", "--mavlink", "udpout:127.0.0.1:14550", "--record", str(path)],
                         capture_output=True, text=True, timeout=60, env={**os.environ, "PYTHONWARNINGS": "ignore"})  # fmt: skip
    assert out.returncode == 2 and out.stderr.count("\n") == 1 and f"--record {path}:" in out.stderr, out.stderr
    assert "Errno" not in out.stderr and "Traceback" not in out.stderr


def test_a_recording_joined_mid_gop_opens_at_a_keyframe_with_its_klv_on_the_pictures(
    source: Path, tmp_path: Path
) -> None:
    """A stream joined between keyframes (as a live RTSP stream is): the file starts at the next
    keyframe, with SPS and PPS, decodes without an error, and each KLV packet is stamped within
    40 ms of a picture."""
    import av

    mid = tmp_path / "mid.ts"
    with av.open(str(source)) as inp, av.open(str(mid), "w", format="mpegts") as out:
        vout = out.add_stream_from_template(inp.streams.video[0])
        packets = [p for p in inp.demux(inp.streams.video[0]) if p.dts is not None]
        for p in packets[3:]:  # the first keyframe and two pictures after it left out
            p.stream = vout
            out.mux(p)
    rec = tmp_path / "rec.ts"
    videos, klvs = remux(str(mid), rec, lambda: {13: 47.0, 14: 8.0}, threading.Event())
    assert videos > 0 and klvs > 0
    rows = subprocess.run(["ffprobe", "-v", "error", "-show_entries", "packet=stream_index,pts_time,flags", "-of",
                           "csv=p=0", str(rec)], capture_output=True, text=True, timeout=60, check=True).stdout  # fmt: skip
    packets_ = [r.split(",")[:3] for r in rows.split() if r]
    video = [(float(t), f) for i, t, f in packets_ if i == "0"]
    klv = [float(t) for i, t, _f in packets_ if i == "1"]
    assert video[0][1].startswith("K"), video[:3]
    with av.open(str(rec)) as c:
        first = bytes(next(p for p in c.demux(c.streams.video[0]) if p.size))
    assert b"\x00\x00\x01\x67" in first and b"\x00\x00\x01\x68" in first  # SPS and PPS before the picture
    errors = subprocess.run(["ffmpeg", "-v", "error", "-i", str(rec), "-map", "0:v", "-f", "null", "-"],
                            capture_output=True, text=True, timeout=60).stderr  # fmt: skip
    assert errors == "", errors
    assert klv and all(min(abs(k - t) for t, _ in video) <= 0.040 for k in klv), (klv, video[:5])
