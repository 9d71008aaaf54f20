"""The C fast path gives exactly what the pure Python parser and decoder give (differential and
property tests), and is in use wherever it was built."""

from __future__ import annotations

import inspect
import random
import subprocess
import sys
from typing import Any

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

import topgimbal
from topgimbal import _speedups
from topgimbal._speedups.spec import codec_spec
from topgimbal.protocol import (
    DIALECT_NAMES,
    Dialect,
    Frame,
    FrameParser,
    Message,
    all_models,
    any_decoder,
    decode_any,
    get_dialect,
    get_model,
    make_frame,
)
from topgimbal.tools.cvectors import sample

from .conftest import (
    FAST_WANTED,
    PureFrameParser,
    ext,
    fast_any_decoder,
    fast_decoder,
    fast_parser_cls,
    pure_any_decoder,
    pure_decode,
)

pytestmark = pytest.mark.loopback

SETTINGS = settings(max_examples=150, deadline=None, suppress_health_check=[HealthCheck.too_slow])
TOKENS = [
    b"#", b"#TP", b"#tp", b"#tP", b"#Tp", b"UG", b"GU", b"DU", b"2w", b"3r", b"Fw", b"\r\n", b"\n", b"\x00",
    b"\xff", b"GAC", b"G!C", b"0011", b"#TPUD2wAWB0144", b"#tpDU3rVER0105025A", b"#tpGUCwGIAFF36ED5A0048AE",
    b"#tPUD\x05wLOC12345", b"#TpUD\x00\x03GPS123",
]  # fmt: skip
streams = st.lists(st.one_of(st.sampled_from(TOKENS), st.binary(max_size=8)), max_size=30).map(b"".join)
plans = st.lists(st.integers(1, 30), min_size=1, max_size=8)


def test_fast_path_is_in_use_where_built() -> None:
    assert topgimbal.speedups_enabled() is _speedups.enabled()
    if FAST_WANTED:  # the test machine has a compiler: `pip install -e .` built the extension
        assert _speedups.enabled(), _speedups.status()


def test_env_var_selects_the_pure_path() -> None:
    code = "import topgimbal, topgimbal._speedups as s; print(topgimbal.speedups_enabled(), s.status())"
    out = subprocess.run(
        [sys.executable, "-c", code],
        env={"TOPGIMBAL_PURE": "1", "PATH": ""},
        capture_output=True,
        text=True,
        check=True,
    ).stdout
    assert out.strip() == "False disabled by TOPGIMBAL_PURE"


def test_missing_extension_falls_back_to_pure_python() -> None:
    """As on a machine without a compiler: the extension cannot be imported, everything works."""
    code = (
        "import sys\n"
        "class Block:\n"
        "    def find_spec(self, name, path=None, target=None):\n"
        "        if name.endswith('_ctop'): raise ImportError('no extension here')\n"
        "sys.meta_path.insert(0, Block())\n"
        "import topgimbal\n"
        "from topgimbal import decode\n"
        "print(topgimbal.speedups_enabled(), decode('topotek', '#tpGPCrGACFF36ED5A0048DE').fields)\n"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True).stdout
    assert out.strip() == "False {'yaw_deg': -2.02, 'pitch_deg': -47.74, 'roll_deg': 0.72}"


def _run(
    cls: type[FrameParser], stream: bytes, plan: list[int], datagrams: bool, decode: Any = None
) -> tuple[list[Any], dict[str, int], int]:
    p = cls(max_data_length=64)
    out: list[Any] = []
    i = k = 0
    while i < len(stream):
        n = plan[k % len(plan)]
        piece = stream[i : i + n]
        if decode is not None:
            out += p.feed_messages(piece, decode, final=datagrams)
        else:
            out += p.feed_datagram(piece) if datagrams else p.feed(piece)
        i += n
        k += 1
    out += p.flush()
    return out, p.stats.as_dict(), p.buffered


@SETTINGS
@given(streams, plans, st.booleans())
def test_scan_matches_pure_parser(stream: bytes, plan: list[int], datagrams: bool) -> None:
    fast = fast_parser_cls()
    assert _run(fast, stream, plan, datagrams) == _run(PureFrameParser, stream, plan, datagrams)


@SETTINGS
@given(streams, plans, st.booleans(), st.sampled_from([None, *DIALECT_NAMES]))
def test_feed_messages_matches_pure_feed_and_decode(
    stream: bytes, plan: list[int], datagrams: bool, prefer: str | None
) -> None:
    """Scan and decode in one C call: the same Messages and Diagnostics as the pure parser followed
    by the pure decoder, with one dialect's decoder and with the cross-dialect one."""
    first = get_dialect(prefer) if prefer else None
    fast_parser = fast_parser_cls()
    if first is not None:
        assert _run(fast_parser, stream, plan, datagrams, fast_decoder(first)) == _run(
            PureFrameParser, stream, plan, datagrams, pure_decode(first)
        )
    assert _run(fast_parser, stream, plan, datagrams, fast_any_decoder(first)) == _run(
        PureFrameParser, stream, plan, datagrams, pure_any_decoder(first)
    )


def test_scan_matches_pure_parser_on_a_long_random_stream() -> None:
    rnd = random.Random(7)
    good = [make_frame("GAC", bytes(rnd.randrange(48, 58) for _ in range(12)), src="G", dst="U").to_bytes()]
    good += [make_frame("GPS", bytes(rnd.randrange(256) for _ in range(14)), header="#tp").to_bytes()]
    parts = [rnd.choice(good + TOKENS) for _ in range(5000)]
    stream = b"".join(p if rnd.random() > 0.05 else p[: rnd.randrange(len(p) + 1)] for p in parts)
    for datagrams in (False, True):
        fast = _run(fast_parser_cls(), stream, [7, 1, 64, 3], datagrams)
        assert fast == _run(PureFrameParser, stream, [7, 1, 64, 3], datagrams)
        assert sum(isinstance(e, Frame) for e in fast[0]) > 300


def test_frame_parser_uses_the_fast_path_where_enabled() -> None:
    """protocol/parser.py adopts the C methods; they read as the pure ones (docs, signature)."""
    for name in _speedups.PARSER_METHODS:
        method = getattr(FrameParser, name)
        pure = getattr(PureFrameParser, name)
        assert (type(method).__name__ == "ParserMethod") is _speedups.enabled()
        assert method.__doc__ == pure.__doc__ and inspect.signature(method) == inspect.signature(pure)


def test_fast_methods_check_their_arguments() -> None:
    p = fast_parser_cls()()
    with pytest.raises(TypeError):
        p.feed()  # type: ignore[call-arg]
    with pytest.raises(TypeError):
        p.flush(b"x")  # type: ignore[call-arg]
    with pytest.raises(TypeError):
        p.feed_messages(b"x", len, datagram=True)  # type: ignore[call-arg]
    with pytest.raises(TypeError):
        p.feed("#TPUD2wAWB0144")  # type: ignore[arg-type]
    assert p.feed(bytearray(b"#TPUD2wAWB0144")) == PureFrameParser().feed(b"#TPUD2wAWB0144")
    assert p.feed_messages(memoryview(b"#TPUD2wAWB0144"), lambda f: f.ident, final=True) == ["AWB"]


def test_a_decoder_that_raises_leaves_the_parser_consistent(parser_cls: type[FrameParser]) -> None:
    """As on the pure path: the bytes are consumed and counted, then the decoder's error propagates."""

    def boom(frame: Frame) -> Any:
        raise RuntimeError(frame.ident)

    p = parser_cls()
    with pytest.raises(RuntimeError, match="AWB"):
        p.feed_messages(b"#TPUD2wAWB0144#TPUD", boom)
    assert p.buffered == 5 and p.stats.frames == 1 and p.stats.bytes == 19


def _same_message(a: Any, b: Any) -> None:
    assert a == b
    if a.fields is not None:
        for k, v in a.fields.items():
            assert type(v) is type(b.fields[k]), (k, v, b.fields[k])


def _all_dialects() -> dict[str, Dialect]:
    """Both dialects as documented, and every model's own build of them (the C11's rate steps)."""
    out = {name: get_dialect(name) for name in DIALECT_NAMES}
    for model in all_models().values():
        d = get_model(model.name)[0]
        if all(d is not other for other in out.values()):
            out[f"{d.name} ({model.name})"] = d
    return out


def _sample_frames(rnd: random.Random) -> list[tuple[str, Frame]]:
    """A frame of every form of every dialect with sample values, plus mutations of its data."""
    out = []
    for name, d in _all_dialects().items():
        for spec in d.commands.values():
            for form in spec.forms:
                for k in range(3):
                    try:
                        values = {f.name: sample(codec_spec(f.codec), k, rnd) for f in form.fields}
                        data = form.encode(values, spec.ident)
                    except (ValueError, topgimbal.TopGimbalError):
                        continue
                    for src, dst in (("U", spec.address), (spec.address, "U"), ("U", "U")):
                        for mutated in (data, _mutate(data, rnd), data[:-1], data.lower(), data.replace(b"0", b" ")):
                            try:
                                frame = make_frame(spec.ident, mutated, src=src, dst=dst, rw=form.rw, header="#tP")
                            except topgimbal.TopGimbalError:
                                continue
                            out.append((name, frame))
    return out


def _mutate(data: bytes, rnd: random.Random) -> bytes:
    if not data:
        return b"0"
    b = bytearray(data)
    b[rnd.randrange(len(b))] = rnd.choice(b"0123456789ABCDEFabcdef-+. #NKkERz\x00\xff")
    return bytes(b)


def test_decoder_matches_pure_decoder_on_every_form() -> None:
    rnd = random.Random(11)
    frames = _sample_frames(rnd)
    dialects = _all_dialects()
    assert len(dialects) > 2  # the models' own builds are among them
    decoders = {name: fast_decoder(d) for name, d in dialects.items()}
    decoded = 0
    for name, frame in frames:
        fast, pure = decoders[name](frame), pure_decode(dialects[name])(frame)
        _same_message(fast, pure)
        decoded += fast.fields is not None
    assert len(frames) > 3000 and decoded > 1500


def test_any_decoder_matches_pure_decode_any_on_every_form() -> None:
    """decode_any in C (each preference, the models' own dialects too) gives what the pure one
    gives, including every merged error text; also for frames built by hand with odd parts."""
    frames = [f for _name, f in _sample_frames(random.Random(5))]
    odd = [f._replace(rw="x") for f in frames[:50]] + [f._replace(src="") for f in frames[50:100]]
    odd += [f._replace(header="#Tp", rw="") for f in frames[100:200]] + [
        f._replace(ident="G\xe9C") for f in frames[:20]
    ]
    decoded = 0
    for prefer in [None, *_all_dialects().values()]:
        fast, pure = fast_any_decoder(prefer), pure_any_decoder(prefer)
        for frame in frames[::3] + odd:
            m = fast(frame)
            _same_message(m, pure(frame))
            decoded += m.fields is not None
    assert decoded > 3000


def test_the_protocol_layer_decodes_on_the_fast_path_where_enabled() -> None:
    d = get_dialect("topotek")
    frame = make_frame("GAC", b"FF36ED5A0048", src="G", dst="P", rw="r", header="#tp")
    assert d.decode(frame) == d._decode_py(frame) and decode_any(frame) == pure_any_decoder(None)(frame)
    assert (type(d.decoder()).__name__ == "Decoder") is _speedups.enabled()
    assert (type(any_decoder("skydroid")).__name__ == "AnyDecoder") is _speedups.enabled()


def test_decode_many_matches_one_by_one() -> None:
    d = get_dialect("skydroid")
    frames = [f for name, f in _sample_frames(random.Random(3)) if name == "skydroid"][:500]
    dec = fast_decoder(d)
    assert dec.decode_many(frames) == [pure_decode(d)(f) for f in frames]  # type: ignore[attr-defined]


@SETTINGS
@given(st.sampled_from(DIALECT_NAMES), st.data())
def test_decoder_matches_pure_decoder_on_random_data(name: str, data: st.DataObject) -> None:
    d = get_dialect(name)
    ident = data.draw(st.sampled_from(sorted(d.commands)))
    payload = data.draw(
        st.one_of(st.binary(max_size=20), st.text("0123456789ABCDEFNSEW. -+abcK", max_size=20).map(str.encode))
    )
    src, dst = data.draw(st.sampled_from([("U", "G"), ("G", "U"), ("D", "P"), ("P", "D")]))
    frame = make_frame(ident, payload, src=src, dst=dst, rw=data.draw(st.sampled_from("rw")), header="#tP")
    _same_message(fast_decoder(d)(frame), pure_decode(d)(frame))


def test_recovered_c12_version_reply_on_both_paths(parser_cls: type[FrameParser]) -> None:
    """The `parser_cls` fixture runs a parser test on each path (pure, and fast where built)."""
    p = parser_cls()
    out = p.feed(b"junk#tpDU3rVER0105025A\r\n#TPUD2wAWB0144")
    frames = [e for e in out if isinstance(e, Frame)]
    assert [(f.ident, f.data, f.declared_length) for f in frames] == [("VER", b"010502", 3), ("AWB", b"01", None)]
    assert p.stats.length_recoveries == 1 and p.stats.bytes_discarded == 4


@pytest.mark.parametrize("index, value", [(1, 256), (1, -1), (9, 200), (12, 2**40)])
def test_decoder_refuses_a_codec_descriptor_out_of_range(index: int, value: int) -> None:
    """The extension's Decoder reads a codec descriptor's small numbers straight into the C struct:
    a width of 256, a negative width, an exponent or a multiplier out of its C type is an
    OverflowError naming nothing half built (not a silently truncated codec)."""
    from topgimbal._speedups.spec import decoder_tables

    sky = get_dialect("skydroid")
    tables = decoder_tables(sky.commands.values())
    # the first natively decoded field of the tables: its descriptor, with one number changed
    c, f, k = next(
        (c, f, k)
        for c, cmd in enumerate(tables)
        for f, form in enumerate(cmd[2])
        for k, fld in enumerate(form[4])
        if fld[3] is not None
    )
    ident, spec, forms, orders = tables[c]
    form = forms[f]
    fld = form[4][k]
    desc = (*fld[3][:index], value, *fld[3][index + 1 :])
    fields = (*form[4][:k], (*fld[:3], desc, *fld[4:]), *form[4][k + 1 :])
    bad_forms = (*forms[:f], (*form[:4], fields), *forms[f + 1 :])
    bad = (*tables[:c], (ident, spec, bad_forms, orders), *tables[c + 1 :])
    args = (Message, pure_decode(sky), sky.name, tuple(sky.headers), sky.host_addresses)
    with pytest.raises(OverflowError):
        ext().Decoder(bad, *args)
    assert ext().Decoder(tables, *args) is not None  # the same tables unchanged build
