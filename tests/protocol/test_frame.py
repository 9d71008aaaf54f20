"""The frame envelope and the streaming parser's specific behaviours (properties are in
test_parser_properties.py)."""

from __future__ import annotations

import pytest

from topgimbal.errors import ChecksumError, FrameError, LengthError
from topgimbal.protocol import Diagnostic, Frame, FrameParser, checksum, dissect, make_frame, parse_frame

pytestmark = pytest.mark.virtual


def test_checksum_is_sum_mod_256_upper_hex() -> None:
    assert checksum(b"#TPUD2wAWB01") == 0x44
    assert make_frame("AWB", "01", dst="D").to_bytes() == b"#TPUD2wAWB0144"


def test_frame_is_immutable_and_swaps_for_replies() -> None:
    f = parse_frame("#TPUG2wPTZ006A")
    with pytest.raises(AttributeError):
        f.src = "P"  # type: ignore[misc]
    r = f.swapped()
    assert (r.src, r.dst, r.ident, r.data) == ("G", "U", "PTZ", b"00")
    assert r.swapped() == f


def test_extended_headers_round_trip() -> None:
    data = bytes(range(200))
    f = make_frame("TMP", data, src="D", dst="P", header="#tP")
    raw = f.to_bytes()
    assert raw[5] == 200 and raw[6:7] == b"w"
    assert parse_frame(raw) == f
    big = make_frame("XXX", b"A" * 300, src="D", dst="P", header="#Tp")
    raw = big.to_bytes()
    assert raw[5:7] == (300).to_bytes(2, "big") and raw[7:10] == b"XXX"
    assert parse_frame(raw) == big and big.rw == ""


@pytest.mark.parametrize(
    ("kwargs", "match"),
    [
        (dict(ident="AB"), "3 ASCII"),
        (dict(ident="ABC", src="X"), "src address"),
        (dict(ident="ABC", rw="x"), "control"),
        (dict(ident="ABC", data="0123456789ABCDEF", header="#tp"), "at most 15"),
        (dict(ident="ABC", header="#XX"), "header"),
    ],
)
def test_make_frame_rejects_bad_parts(kwargs: dict, match: str) -> None:  # type: ignore[type-arg]
    with pytest.raises(FrameError, match=match):
        make_frame(**kwargs)


def test_parse_frame_errors_say_what_is_wrong() -> None:
    with pytest.raises(ChecksumError) as exc:
        parse_frame("#TPUG2wPTZ006B")
    assert exc.value.expected == "6A" and exc.value.found == "6B"
    with pytest.raises(FrameError, match="header"):
        parse_frame("#XPUG2wPTZ006A")
    with pytest.raises(FrameError, match="address 'Q'"):
        parse_frame("#TPQG2wPTZ006A")
    with pytest.raises(LengthError, match="length character"):
        parse_frame("#TPUGZwPTZ006A")
    with pytest.raises(FrameError, match="shorter"):
        parse_frame("#TPUG2w")
    assert parse_frame("#tpUM2wZMC009C\r\n").ident == "ZMC"  # CR LF ending accepted
    assert parse_frame("#TPUG2wPTZ006a").data == b"00"  # lower-case checksum accepted


def test_dissect_reports_parts_of_a_bad_frame() -> None:
    d = dissect(b"#TPUG6wGAYEF073288")
    assert not d.ok and d.frame is None
    assert (d.header, d.src, d.dst, d.length, d.rw, d.ident, d.data) == ("#TP", "U", "G", 6, "w", "GAY", b"EF0732")
    assert d.checksum == "88" and d.expected_checksum == "48"


def test_parser_several_frames_per_datagram_and_crlf() -> None:
    p = FrameParser()
    out = p.feed(b"#TPUG2wPTZ006A\r\n#tpGUCrGACFF36ED5A0048E3\r\n")
    assert [e.ident for e in out if isinstance(e, Frame)] == ["PTZ", "GAC"]
    assert not [e for e in out if isinstance(e, Diagnostic)]
    assert p.stats.frames == 2 and p.stats.bytes_discarded == 0 and p.buffered == 0


def test_parser_garbage_then_good_frame_is_not_held_back() -> None:
    """A garbage '#' claiming a long frame must not delay a complete good frame behind it."""
    p = FrameParser()
    out = p.feed(b"#TPUGFw" + b"#TPUG2wPTZ006A")
    frames = [e for e in out if isinstance(e, Frame)]
    assert frames == [parse_frame("#TPUG2wPTZ006A")]
    assert p.stats.resyncs >= 1 and p.buffered == 0


def test_parser_extended_length_bound() -> None:
    p = FrameParser(max_data_length=64)
    out = p.feed(b"#TpPD\xff\xffABC" + b"#TPUG2wPTZ006A")
    assert any(isinstance(e, Diagnostic) and e.kind == "oversize" for e in out)
    assert [e for e in out if isinstance(e, Frame)] == [parse_frame("#TPUG2wPTZ006A")]
    assert p.stats.oversize == 1


def test_parser_bad_checksum_drops_only_that_frame() -> None:
    p = FrameParser()
    out = p.feed(b"#TPUG2wPTZ006B#TPUG2wPTZ016B")
    kinds = [e.kind if isinstance(e, Diagnostic) else e.ident for e in out]
    assert kinds == ["bad_checksum", "PTZ"]
    assert p.stats.bad_checksums == 1 and p.stats.frames == 1


def test_parser_waits_for_a_split_frame_and_flush_reports_leftovers() -> None:
    p = FrameParser()
    assert p.feed(b"#TPUG2wPT") == []
    assert p.buffered == 9
    assert p.feed(b"Z006A") == [parse_frame("#TPUG2wPTZ006A")]
    assert p.feed(b"#TPUG2") == []
    left = p.flush()
    assert len(left) == 1 and isinstance(left[0], Diagnostic) and p.buffered == 0


def test_length_recovery_can_be_switched_off() -> None:
    p = FrameParser(recover_length=False)
    out = p.feed(b"#tpDU3rVER0105025A")
    assert not [e for e in out if isinstance(e, Frame)]
    assert p.stats.bad_checksums == 1


def test_recovered_frame_waits_for_a_boundary_on_a_stream() -> None:
    """On a byte stream the real C12 VER answer is delivered once the next frame shows where it
    ends; as a datagram it is delivered at once."""
    p = FrameParser()
    out: list[Frame | Diagnostic] = []
    for b in b"#tpDU3rVER0105025A":
        out += p.feed(bytes([b]))
    assert not [e for e in out if isinstance(e, Frame)]
    out += p.feed(b"#TPUG2wPTZ006A")
    frames = [e for e in out if isinstance(e, Frame)]
    assert [f.ident for f in frames] == ["VER", "PTZ"] and frames[0].data == b"010502"
    assert frames[0].declared_length == 3 and frames[0].to_bytes() == b"#tpDU3rVER0105025A"
    d = FrameParser().feed_datagram(b"#tpDU3rVER0105025A")
    assert [e.kind if isinstance(e, Diagnostic) else e.ident for e in d] == ["length_mismatch", "VER"]


def test_recovery_needs_an_exact_fit_not_a_chance_checksum() -> None:
    """`#tpUD8wVER87ABBC9EA72` (9 data characters, length 8): at 14 bytes the 2-character reading
    happens to have a right checksum; it must not be taken."""
    raw = b"#tpUD8wVER87ABBC9EA72"
    assert raw[12:14] == b"AB" and sum(raw[:12]) & 0xFF == 0xAB  # the chance match
    p = FrameParser()
    out: list[Frame | Diagnostic] = []
    for b in raw + b"\r\n":
        out += p.feed(bytes([b]))
    frames = [e for e in out if isinstance(e, Frame)]
    assert len(frames) == 1 and frames[0].data == b"87ABBC9EA"


def test_truncated_frame_before_a_good_one_is_not_held() -> None:
    p = FrameParser()
    out = p.feed(b"#TPUD2w#TPUD2wAWB0144")
    assert [e for e in out if isinstance(e, Frame)] == [parse_frame("#TPUD2wAWB0144")]
    assert p.buffered == 0


def test_overlong_length_character_is_recovered_when_a_frame_follows() -> None:
    p = FrameParser()
    out = p.feed(b"#TPUGFwPTZ1E#TPUD2wAWB0144")
    kinds = [e.kind if isinstance(e, Diagnostic) else e.ident for e in out]
    assert kinds == ["length_mismatch", "PTZ", "AWB"]


def test_complete_frame_appends_only_a_missing_checksum() -> None:
    from topgimbal.protocol.frame import complete_frame

    assert complete_frame("#TPUD2rVER00") == b"#TPUD2rVER0051"
    assert complete_frame(" #TPUD2rVER0051\r\n") == b"#TPUD2rVER0051"
    with pytest.raises(ChecksumError, match="expected '51'"):
        complete_frame("#TPUD2rVER00ZZ")  # a wrong checksum is reported, never replaced
    with pytest.raises(FrameError):
        complete_frame("#TPUD3rVER00")  # length 3 with 2 data characters: not completed
    with pytest.raises(FrameError, match="header"):
        complete_frame("#hello world")


# -- issue 9: identifiers, header/control agreement, text() ---------------------------------------


@pytest.mark.parametrize("ident", ["G#C", "GA\xe9", "G C", "ga-", "GA", "GACX", "\x00AB"])
def test_identifier_must_be_three_ascii_letters_or_digits(ident: str) -> None:
    with pytest.raises(FrameError, match="3 ASCII letters or digits"):
        make_frame(ident, "01", dst="D")
    if len(ident) != 3:
        return  # on the wire another length is just other bytes in the identifier's place
    body = b"#TPUD2w" + ident.encode("latin-1") + b"01"
    raw = body + b"%02X" % (sum(body) & 0xFF)
    assert not dissect(raw).ok
    parser = FrameParser()
    assert [o for o in parser.feed_datagram(raw) if isinstance(o, Frame)] == []


def test_identifiers_with_digits_and_lower_case_are_frames() -> None:
    for ident in ("PA2", "gac", "H2O"):
        frame = make_frame(ident, "01", dst="D")
        assert FrameParser().feed_datagram(frame.to_bytes()) == [frame]


def test_a_read_cannot_be_spelled_with_the_16_bit_length_header() -> None:
    with pytest.raises(FrameError, match="#Tp frame has no control character"):
        make_frame("GPS", b"\x00" * 20, dst="D", rw="r", header="#Tp")
    assert make_frame("GPS", b"\x00" * 20, dst="D", rw="w", header="#Tp").rw == ""


def test_text_escapes_what_is_not_printable_and_never_raises() -> None:
    binary = Frame("#tP", "U", "D", "w", "GPS", b"\x00#\\ab\r\n\xff")
    text = binary.text()
    assert text.isascii() and text.isprintable()
    assert "\\x00#\\\\ab\\x0d\\x0a\\xff" in text
    # Frames built by hand with parts no wire can carry still render (logs and consoles show them).
    for bad in (
        Frame("#TP", "U", "D", "w", "G\u00e9S", b""),
        Frame("#XX", "U", "D", "w", "GAC", b""),
        Frame("#TP", "U", "D", "w", "GAC", b"x" * 40),
        Frame("#TP", "\u4e2d", "D", "?", "GAC", b""),
    ):
        t = bad.text()
        assert t.isascii() and t.isprintable()
