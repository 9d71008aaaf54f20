"""The C extension's objects misused the way Python code can misuse them: a clear TypeError or
ValueError, never a crash, and the same answer as the pure path for any input it takes.

Crashes are probed in a child interpreter so that a regression fails one test, not the run."""

from __future__ import annotations

import array
import subprocess
import sys
import textwrap
from pathlib import Path
from typing import Any

import pytest

from topgimbal._speedups.spec import decoder_tables
from topgimbal.protocol import Frame, Message, get_dialect, make_frame

from .conftest import PureFrameParser, ext, fast_decoder, fast_parser_cls, pure_decode

pytestmark = pytest.mark.loopback

ROOT = Path(__file__).resolve().parents[2]
GOOD = make_frame("GAC", b"00", src="U", dst="G").to_bytes()


def _child(code: str) -> subprocess.CompletedProcess[str]:
    prelude = "from topgimbal._speedups import load_extension\next = load_extension()\n"
    return subprocess.run(
        [sys.executable, "-c", prelude + textwrap.dedent(code)], capture_output=True, text=True, timeout=60
    )


@pytest.mark.parametrize(
    "use",
    [
        "d(make_frame('GAC', b'00', src='U', dst='G'))",
        "d.decode_many([make_frame('GAC', b'00', src='U', dst='G')])",
        "d.dialect",
        "ext.AnyDecoder(d, (), print)",
        "ext.AnyDecoder(None, (d,), print)",
    ],
)
def test_a_decoder_without_tables_is_a_type_error(use: str) -> None:
    """Decoder.__new__ alone (no __init__) used to be read through a NULL table: a segfault."""
    r = _child(
        f"""
        from topgimbal.protocol import make_frame
        d = ext.Decoder.__new__(ext.Decoder)
        try:
            {use}
        except TypeError as exc:
            print("TypeError:", exc)
        """
    )
    assert r.returncode == 0, r.stderr[-500:]
    assert "TypeError: Decoder is not initialised" in r.stdout


def _tables() -> tuple[Any, ...]:
    return tuple(decoder_tables(get_dialect("skydroid").commands.values()))


def _decoder_args(commands: tuple[Any, ...]) -> tuple[Any, ...]:
    d = get_dialect("skydroid")
    return (commands, Message, pure_decode(d), d.name, tuple(d.headers), d.host_addresses)


def _with_command(k: int, command: tuple[Any, ...]) -> tuple[Any, ...]:
    tables = _tables()
    return (*tables[:k], command, *tables[k + 1 :])


def _bad_tables() -> list[tuple[str, tuple[Any, ...]]]:
    tables = _tables()
    k = next(i for i, c in enumerate(tables) if c[0] == b"GAC")
    ident, spec, forms, orders = tables[k]
    rsp = next(i for i, f in enumerate(forms) if f[4])  # a form with fields
    form = forms[rsp]
    field = form[4][0]
    far = (field[0], form[2] + 5, *field[2:])  # a field past the form's shortest data
    return [
        ("order index past the forms", _with_command(k, (ident, spec, forms, (((99,), ()), ((), ()))))),
        ("orders of the wrong shape", _with_command(k, (ident, spec, forms, ((), ())))),
        ("forms not a tuple", _with_command(k, (ident, spec, list(forms), orders))),
        (
            "field past the data",
            _with_command(
                k, (ident, spec, (*forms[:rsp], (*form[:4], (far, *form[4][1:])), *forms[rsp + 1 :]), orders)
            ),
        ),
        ("min_len above max_len", _with_command(k, (ident, spec, ((form[0], form[1], 9, 2, ()),), orders))),
    ]


def check_bad_table(case: int) -> None:
    """A malformed table raises, leaves the Decoder unusable, and a good one may follow."""
    what, commands = _bad_tables()[case]
    d = ext().Decoder.__new__(ext().Decoder)
    with pytest.raises((ValueError, TypeError)):
        d.__init__(*_decoder_args(commands))
    with pytest.raises(TypeError, match="not initialised"):
        d(make_frame("GAC", b"00", src="U", dst="G", rw="r"))
    d.__init__(*_decoder_args(_tables()))  # a failed __init__ may be retried
    assert d(make_frame("GAC", b"00", src="U", dst="G", rw="r")).error is None, what


@pytest.mark.parametrize("case", range(5))
def test_a_malformed_table_is_refused_and_leaves_no_half_decoder(case: int) -> None:
    """Tables that would index past an array used to be taken as given (an out-of-bounds read on
    the first frame, or a segfault); a failed __init__ kept the commands built before the bad one."""
    r = subprocess.run(
        [sys.executable, "-c", f"from tests.speedups.test_ctop_misuse import check_bad_table; check_bad_table({case})"],
        capture_output=True,
        text=True,
        timeout=60,
        cwd=ROOT,
    )
    assert r.returncode == 0, r.stderr[-800:]


@pytest.mark.parametrize("data", [5, None, 1.5, object()])
def test_feed_of_a_non_sequence_is_the_pure_paths_type_error(data: Any) -> None:
    """feed(5) used to go through bytes(5): five NUL bytes on the C path (bytes(10**9) a gigabyte
    of them) where the pure path raises TypeError; now both raise the same error."""
    errors = []
    for cls in (fast_parser_cls(), PureFrameParser):
        p = cls()
        with pytest.raises(TypeError) as info:
            p.feed(data)
        errors.append(str(info.value))
        assert p.stats.bytes == 0 and p.buffered == 0
    assert errors[0] == errors[1]


@pytest.mark.parametrize(
    "data",
    [bytearray(GOOD), memoryview(GOOD), memoryview(b"xx" + GOOD)[2:], array.array("b", GOOD), GOOD + GOOD[:5]],
    ids=["bytearray", "memoryview", "memoryview-slice", "array", "bytes"],
)
def test_feed_of_bytes_like_data_matches_the_pure_path(data: Any) -> None:
    out = []
    for cls in (fast_parser_cls(), PureFrameParser):
        p = cls()
        events = p.feed(data) + p.feed(data) + p.flush()
        out.append((events, p.stats.bytes, p.stats.frames, p.buffered))
    assert out[0] == out[1]
    assert out[0][2] >= 2


def test_feed_counts_bytes_as_the_pure_path_for_wide_items() -> None:
    """An array of 4-byte items: len() counts items, bytes() gives 4 per item. The statistics
    follow the pure path (len) instead of the C path's own count, as the C docs promise."""
    data: Any = array.array("i", [0x23232323, 0])
    stats = []
    for cls in (fast_parser_cls(), PureFrameParser):
        p = cls()
        p.feed(data)
        stats.append(p.stats.bytes)
    assert stats[0] == stats[1] == 2


@pytest.mark.parametrize("wrap", [bytes, bytearray, memoryview])
def test_decode_of_bytes_like_and_huge_data_matches_the_pure_path(wrap: Any) -> None:
    d = get_dialect("skydroid")
    fast, pure = fast_decoder(d), pure_decode(d)
    for data in (b"00", b"0" * 12, b"0" * (1 << 20)):
        for rw in ("r", "w", ""):
            frame = Frame("#Tp" if not rw else "#tp", "U", "G", rw, "GAC", wrap(data), None)
            a, b = fast(frame), pure(frame)
            assert (a.form, a.fields, a.error) == (b.form, b.fields, b.error)


def test_huge_streams_are_scanned_without_holding_them() -> None:
    junk = bytes(range(256)).replace(b"#", b"x") * 4096  # 1 MB without a frame start
    p = fast_parser_cls()()
    events = p.feed(junk + GOOD)
    assert [type(e).__name__ for e in events] == ["Diagnostic", "Frame"] and p.buffered == 0
    view: Any = memoryview(b"#Tp" + b"x" * (1 << 20))
    events = p.feed_datagram(view)
    assert p.buffered == 0 and all(type(e).__name__ == "Diagnostic" for e in events)
