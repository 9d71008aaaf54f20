"""What the frame parser reports besides frames: a `Diagnostic` for bytes it discarded or a length
it recovered, and its running `ParserStats`. The reason codes are the C scanner's (enum tg_reason in
c/include/topgimbal.h), so both paths word their diagnostics from this one table."""

from __future__ import annotations

from dataclasses import dataclass

# Why bytes were discarded, by the C scanner's reason codes (enum tg_reason in c/include/topgimbal.h):
# the pure scan words its diagnostics with the same table, so both paths read the same.
OUTSIDE, BAD_HEADER, OVERSIZE, INCOMPLETE_FOLLOWED, END_OF_STREAM, INNER_FRAME, BAD_CHECKSUM, RECOVERED = range(1, 9)
WHY = {
    OUTSIDE: "bytes outside a frame",
    BAD_HEADER: "'#' not followed by a valid header/address/length",
    INCOMPLETE_FOLLOWED: "incomplete frame followed by a good one",
    END_OF_STREAM: "incomplete frame at end of stream",
    INNER_FRAME: "checksum matched by chance: a frame starts inside",
}


@dataclass(frozen=True)
class Diagnostic:
    """Something the parser noticed: `kind` is one of KINDS, `raw` the bytes concerned."""

    kind: str
    detail: str
    raw: bytes = b""

    KINDS = ("garbage", "bad_header", "bad_length", "oversize", "bad_checksum", "length_mismatch")


@dataclass
class ParserStats:
    frames: int = 0
    bytes: int = 0
    bad_checksums: int = 0
    resyncs: int = 0
    bytes_discarded: int = 0
    length_recoveries: int = 0
    oversize: int = 0

    def as_dict(self) -> dict[str, int]:
        return dict(self.__dict__)
