"""`topgimbal geotag PHOTOS... --log LOG`: write the vehicle's position (EXIF GPS) and the gimbal
pose (XMP) into photos from a camera that was not fed, from a log of the flight (geotag_track.py).

Each photo's capture time: the log's CAP answer with the photo's file index where the log has one
from the photo's own camera (the index in the name: snap_0_<n>.jpeg, IMG_<n>.jpg), else its EXIF
DateTimeOriginal plus `--offset` seconds (the camera's clock minus UTC, negated), read as UTC. A
photo whose clock was never set (before 2000) and that matched by index also gets the log's time as
DateTimeOriginal.

Which camera's capture (`_match`): a .tlog may hold the captures of several cameras on one vehicle,
each numbering its photos from 1. A capture is another camera's when its file_url names another
file, its component's CAMERA_INFORMATION names another vendor than the photo's EXIF Make, or (the
photo's clock set) it was taken more than MATCH_TOLERANCE_S from the photo's DateTimeOriginal. With
captures from several components, one is used only when the photo confirms it (same file, same
model, or the clock agrees); what stays ambiguous is refused, naming `--camera-compid`.
Files (`_read_photo`, `_write_photo`): only regular files are read (a FIFO is never opened for a
blocking read), a read-only photo is refused, a symlink is written through to its target, a
hard-linked photo is rewritten in place, any other whole or not at all with its mode kept.

Photos that already have GPS are left alone unless `--overwrite`. The picture itself is not
re-encoded: only the EXIF and XMP segments change. A bad file is reported on stderr and the others
go on; the exit status is 1 when any photo was not tagged."""

from __future__ import annotations

import argparse
import contextlib
import datetime
import io
import math
import os
import re
import stat
import sys
import tempfile
import warnings
from pathlib import Path

from ..errors import TopGimbalError
from .geotag_track import Capture, Track, TrackError, load_track

INDEX_IN_NAME = re.compile(r"^(?:snap_\d_|IMG_|DJI_)(\d+)", re.IGNORECASE)
PHOTO_SUFFIXES = {".jpg", ".jpeg"}
CLOCK_NEVER_SET_YEAR = 2000
MAX_PHOTO_BYTES = 256 * 1024 * 1024  # a photo larger than this is refused, not read into memory
# A capture and the photo's DateTimeOriginal this far apart are not the same shot: EXIF keeps whole
# seconds (up to 1 s early), the CAP answer and the log add latency. Two cameras fired within this
# window were at nearly the same place, so a match inside it cannot move a photo far.
MATCH_TOLERANCE_S = 3.0


def _seconds(text: str) -> float:
    try:
        v = float(text)
    except ValueError:
        v = math.nan
    if not math.isfinite(v):
        raise argparse.ArgumentTypeError(f"{text!r} is not a number of seconds")
    return v


def register(subparsers: argparse._SubParsersAction[argparse.ArgumentParser]) -> None:
    p = subparsers.add_parser(
        "geotag",
        help="write GPS and gimbal pose into photos from a log (traffic .jsonl or MAVLink .tlog)",
        description=__doc__.split("\n\n")[0] if __doc__ else None,
    )
    p.add_argument("photos", nargs="+", metavar="PHOTO", help="JPEG files or folders of them")
    p.add_argument("--log", required=True, metavar="LOG", help="the client's traffic log (JSONL) or a MAVLink .tlog")
    p.add_argument("--offset", type=_seconds, default=0.0, metavar="S",
                   help="seconds to add to a photo's DateTimeOriginal to get UTC (default 0)")  # fmt: skip
    p.add_argument("--max-gap", type=_seconds, default=10.0, metavar="S",
                   help="no position across a gap in the log longer than S seconds (default 10)")  # fmt: skip
    p.add_argument("--camera-compid", type=int, default=None, metavar="N",
                   help="a .tlog with several cameras: match photos by number only to component N's captures")  # fmt: skip
    p.add_argument("--overwrite", action="store_true", help="replace GPS tags a photo already has")
    p.add_argument("--dry-run", action="store_true", help="say what would be written, change nothing")
    p.set_defaults(func=run)


def _photos(items: list[str]) -> list[Path]:
    out: list[Path] = []
    for item in items:
        p = Path(item)
        if p.is_dir():
            out += sorted(q for q in p.iterdir() if q.suffix.lower() in PHOTO_SUFFIXES and q.is_file())
        else:
            out.append(p)
    return out


def run(args: argparse.Namespace) -> int:
    try:
        track = load_track(Path(args.log))
    except FileNotFoundError:
        raise TrackError(f"--log {args.log}: no such file") from None
    except OSError as exc:
        raise TrackError(f"--log {args.log}: {exc.strerror or exc}") from None
    track.max_gap_s = args.max_gap
    photos = _photos(args.photos)
    if not photos:
        print("topgimbal geotag: no JPEG photo given (files or folders of *.jpg / *.jpeg)", file=sys.stderr)
        return 2
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # Pillow warns on corrupt EXIF and uses what it could read: so do we
        failed = _tag_all(photos, track, args)
    print(f"topgimbal geotag: {len(photos) - failed} of {len(photos)} photos tagged", file=sys.stderr)
    return 1 if failed else 0


def _tag_all(photos: list[Path], track: Track, args: argparse.Namespace) -> int:
    """Tag each photo; a failure is reported and the next one goes on. Returns how many failed."""
    failed = 0
    for path in photos:
        try:
            print(tag_photo(path, track, offset_s=args.offset, overwrite=args.overwrite, dry_run=args.dry_run,
                            camera_compid=args.camera_compid))  # fmt: skip
        except (TopGimbalError, OSError, ValueError) as exc:
            failed += 1
            print(f"topgimbal geotag: {path}: {exc}", file=sys.stderr)
        except Exception as exc:  # a file no reader expected (Pillow's parsers raise many kinds): go on
            failed += 1
            print(f"topgimbal geotag: {path}: unreadable metadata ({type(exc).__name__}: {exc})", file=sys.stderr)
    return failed


class GeotagError(TopGimbalError, ValueError):
    pass


def _shot(name: str) -> str:
    """A file name without its lens marker and suffix: snap_0_6.jpeg and snap_1_6.jpeg are one shot."""
    stem = name.rsplit(".", 1)[0].lower()
    stem = re.sub(r"^snap_[01]_", "snap_", stem)
    return stem[:-2] if stem.endswith("_t") else stem


def _photo_vendor(make: object, name: str) -> str | None:
    if isinstance(make, str) and make.strip("\x00 "):
        return make.strip("\x00 ").split(" ")[0].lower()
    return "topotek" if name.lower().startswith("snap_") else None  # TOPOTEK's own naming


def _at(t: float) -> str:
    return f"{datetime.datetime.fromtimestamp(t, datetime.timezone.utc):%Y-%m-%d %H:%M:%S} UTC"


def _match(
    name: str, cands: list[Capture], track: Track, clock_t: float | None, vendor: str | None, model: str | None,
    chosen: int | None,
) -> Capture | None:  # fmt: skip
    """The capture of this photo among the log's captures with its file index (`cands`), None when
    none is its camera's; raises GeotagError when the log cannot tell (module docstring)."""
    if chosen is not None:
        cands = [c for c in cands if c.compid == chosen]

    def other_camera(c: Capture) -> bool:
        return bool((c.file_name and _shot(c.file_name) != _shot(name)) or (c.vendor and vendor and c.vendor != vendor))

    def clock_disagrees(c: Capture) -> bool:
        return chosen is None and clock_t is not None and abs(c.t - clock_t) > MATCH_TOLERANCE_S

    def confirmed(c: Capture) -> bool:
        return bool((c.file_name and _shot(c.file_name) == _shot(name)) or (c.vendor and c.vendor == vendor)
                    or (c.model and model and c.model == model)
                    or (clock_t is not None and abs(c.t - clock_t) <= MATCH_TOLERANCE_S))  # fmt: skip

    own = [c for c in cands if not other_camera(c)]
    fits = [c for c in own if not clock_disagrees(c)]
    cameras = sorted(str(k) for k in track.cameras() if k is not None)
    several = len(cameras) > 1 and chosen is None
    if fits and not several:
        return fits[-1]
    if fits:
        sure = [c for c in fits if confirmed(c)]
        if sure and len({c.compid for c in sure}) == 1:
            return sure[-1]
        which = ", ".join(sorted({c.camera() for c in fits}))
        raise GeotagError(f"the log has captures from components {', '.join(cameras)} and photo {cands[0].index} "
                          f"could be {which}'s: give --camera-compid N (nothing in the photo says which)")  # fmt: skip
    doubtful = [c for c in own if clock_disagrees(c)]
    if doubtful:
        c = doubtful[-1]
        assert clock_t is not None
        raise GeotagError(f"the log's capture {c.index} ({c.camera()}) was at {_at(c.t)}, this photo's clock says "
                          f"{_at(clock_t)}: another camera's? --camera-compid {c.compid if c.compid is not None else 'N'} "
                          "matches it by number anyway; --offset S corrects a clock that was off")  # fmt: skip
    return None


def tag_photo(
    path: Path, track: Track, *, offset_s: float = 0.0, overwrite: bool = False, dry_run: bool = False,
    camera_compid: int | None = None,
) -> str:  # fmt: skip
    """Tag one photo; returns what was done, raises GeotagError / OSError saying why not."""
    from PIL import Image, UnidentifiedImageError

    from ..video.exif import (
        EXIF_TIME,
        IFD_EXIF,
        IFD_GPS,
        TAG_MAKE,
        TAG_MODEL,
        TAG_ORIGINAL,
        TAG_SUBSEC_ORIGINAL,
        ExifError,
        PhotoMeta,
        Pose,
        tag_jpeg,
    )

    data, st = _read_photo(path)
    try:
        with Image.open(io.BytesIO(data)) as img:
            if img.format != "JPEG":
                raise GeotagError(f"not a JPEG ({img.format})")
            exif = img.getexif()
    except (UnidentifiedImageError, OSError, SyntaxError) as exc:
        raise GeotagError(f"not a readable picture: {exc}") from None
    if exif.get_ifd(IFD_GPS).get(2) and not overwrite:
        return f"{path}: has GPS already (--overwrite replaces it)"
    taken: datetime.datetime | None = None
    text = exif.get_ifd(IFD_EXIF).get(TAG_ORIGINAL)
    if isinstance(text, str):
        try:
            taken = datetime.datetime.strptime(text.strip("\x00 "), EXIF_TIME)
        except ValueError:
            taken = None
    sub_s = exif.get_ifd(IFD_EXIF).get(TAG_SUBSEC_ORIGINAL)  # the fraction of that second, as digits
    if taken is not None and isinstance(sub_s, str) and sub_s.strip("\x00 ").isdigit():
        taken += datetime.timedelta(seconds=float("0." + sub_s.strip("\x00 ")[:6]))
    clock_set = taken is not None and taken.year >= CLOCK_NEVER_SET_YEAR
    clock_t = taken.replace(tzinfo=datetime.timezone.utc).timestamp() + offset_s if taken and clock_set else None
    m = INDEX_IN_NAME.match(path.name)
    index = int(m.group(1)) if m else None
    model = exif.get(TAG_MODEL)
    capture = None
    if index is not None:
        capture = _match(path.name, track.captures_of(index), track, clock_t,
                         _photo_vendor(exif.get(TAG_MAKE), path.name),
                         model.strip("\x00 ") if isinstance(model, str) else None, camera_compid)  # fmt: skip
    new_time = None
    if capture is not None:
        t, how = (
            capture.t,
            f"photo {capture.index}'s capture in the log"
            + (f", {capture.camera()}" if capture.compid is not None else ""),
        )
        if not clock_set:
            new_time = datetime.datetime.fromtimestamp(t, datetime.timezone.utc).replace(tzinfo=None)
    elif taken is not None and clock_t is not None:
        t = clock_t
        how = f"DateTimeOriginal {taken:%Y-%m-%d %H:%M:%S}" + (f" {offset_s:+g} s" if offset_s else "")
    else:
        raise GeotagError("no capture time: no CAP for its file index in the log, and no DateTimeOriginal set "
                          "by a clock (give the camera's time with TIM / UTC, or use --offset)")  # fmt: skip
    at = track.at(t)
    if at is None:
        when = datetime.datetime.fromtimestamp(t, datetime.timezone.utc)
        raise GeotagError(f"the log has no position at {when:%Y-%m-%d %H:%M:%S} UTC (from {how})")
    pose = track.pose_at(t)
    meta = PhotoMeta(time=new_time, lat_deg=at.lat_deg, lon_deg=at.lon_deg, alt_m=at.alt_m,
                     gimbal=Pose(*pose) if pose is not None else None)  # fmt: skip
    summary = f"{path}: {at.lat_deg:.7f}, {at.lon_deg:.7f}, {at.alt_m:.1f} m (matched by {how})"
    if dry_run:
        return summary + " [dry run]"
    try:
        out = tag_jpeg(data, meta, base=exif)
    except ExifError as exc:
        raise GeotagError(str(exc)) from None
    _write_photo(path, st, out)
    return summary


def _read_photo(path: Path) -> tuple[bytes, os.stat_result]:
    """The photo's bytes and status, refusing what geotag must not read or write: anything but a
    regular file (a FIFO named .jpg would block forever; it is opened non-blocking and never read),
    and a file over MAX_PHOTO_BYTES."""
    try:
        fd = os.open(path, os.O_RDONLY | os.O_NONBLOCK | getattr(os, "O_NOCTTY", 0))
    except IsADirectoryError:
        raise GeotagError("a folder, not a photo") from None
    with os.fdopen(fd, "rb") as fh:
        st = os.fstat(fh.fileno())
        if not stat.S_ISREG(st.st_mode):
            raise GeotagError("not a regular file (a FIFO, device or socket): not read, not written")
        if st.st_size > MAX_PHOTO_BYTES:
            raise GeotagError(f"{st.st_size} bytes: larger than a photo ({MAX_PHOTO_BYTES} at most)")
        data = fh.read(MAX_PHOTO_BYTES + 1)
    if len(data) > MAX_PHOTO_BYTES:
        raise GeotagError(f"larger than a photo ({MAX_PHOTO_BYTES} bytes at most)")
    return data, st


def _write_photo(path: Path, st: os.stat_result, out: bytes) -> None:
    """Write the tagged bytes to the file `path` names, keeping what the user made of it: through a
    symlink to its target (the link stays a link), into the same inode when the file has other hard
    links (every name sees the tags), else whole or not at all (a temporary file in the same folder,
    given the photo's mode, renamed over it)."""
    if not st.st_mode & stat.S_IWUSR:  # checked on the mode, not by trying: root may write anything
        raise GeotagError(f"read-only (mode {stat.S_IMODE(st.st_mode):04o}): not changed (chmod u+w to tag it)")
    real = Path(os.path.realpath(path))
    if st.st_nlink > 1:
        with real.open("r+b") as fh:  # the same inode: its other names keep pointing at it
            fh.write(out)
            fh.truncate()
            fh.flush()
            os.fsync(fh.fileno())
        return
    fd, tmp = tempfile.mkstemp(dir=real.parent, prefix=f".{real.name}.", suffix=".geotag-tmp")
    try:
        with os.fdopen(fd, "wb") as fh:
            os.fchmod(fh.fileno(), stat.S_IMODE(st.st_mode))
            fh.write(out)
            fh.flush()
            os.fsync(fh.fileno())
        os.replace(tmp, real)
    except BaseException:
        with contextlib.suppress(OSError):
            os.unlink(tmp)
        raise
