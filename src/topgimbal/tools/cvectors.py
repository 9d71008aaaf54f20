"""Test vectors for libtopgimbal, produced by the Python side (catalog, codecs, FrameParser).

For every form of both dialects: the frame Python encodes from sample values (checked against the
C encoder, whose frame must also decode back to the same values with the C decoder), what Python
decodes from it (checked against the C decoder), and streams holding it valid, with a bad checksum,
with a wrong length character and inside garbage, with every frame and diagnostic the Python
parser reports (checked against the C parser, whole and byte at a time). Besides the three fixed
samples (lowest, highest or defaults, random), EXTRA_SAMPLES random valid values per form, drawn
with the fixed-point edges (the range's ends and their neighbours, 0, one step either side of it)
weighted in, make the encode side a bounded differential test of the two encoders.

Line format (read by c/tests/run_vectors.c), tokens separated by one space:
    M <dialect> <frame hex> <status> <form> <n> <value>...      decode
    N <dialect> <cmd> <form> <src><dst> <frame hex> <n> <value>...  encode
    S <dialect> <stream hex>            stream, followed by its events and a lone '.'
    F <header> <src><dst><rw|-> <ident> <data hex|-> <declared|->
    D <diag> <raw hex>
Values: n:<mantissa>e<exp10>  z (null)  e:<index>  t:<hex>  b:<hex>  d:YYYYMMDDHHMMSScc  a (absent)
"""

from __future__ import annotations

import random
from datetime import datetime, timedelta
from decimal import Decimal
from typing import Any

from .._speedups.spec import CodecSpec, codec_spec
from ..errors import TopGimbalError
from ..protocol import Diagnostic, Frame, make_frame
from ..protocol.catalog import REQUEST, CommandSpec, Dialect, Form
from ..protocol.parser import PureFrameParser

DIAG = {
    "garbage": 1,
    "bad_header": 2,
    "bad_length": 3,
    "oversize": 4,
    "bad_checksum": 5,
    "length_mismatch": 6,
}
HEADER = {"#TP": 1, "#tp": 2, "#tP": 3, "#Tp": 4}
NUMBER_KINDS = {"hexint", "decint", "binint", "decfloat", "bitrate", "geodm", "geodeg"}
EXTRA_SAMPLES = 8  # random valid value sets per form beyond the three fixed ones
_TEXT_CHARS = "".join(chr(c) for c in range(0x20, 0x7F) if chr(c) != "#")  # what a text field may carry


class VectorError(Exception):
    """A Python value the C representation cannot hold exactly."""


def number_token(value: Any, exp10: int) -> str:
    m = Decimal(repr(value)).scaleb(-exp10)
    if m != m.to_integral_value():
        raise VectorError(f"{value!r} is not a multiple of 10^{exp10}")
    return f"n:{int(m)}e{exp10}"


def value_token(spec: CodecSpec, value: Any) -> str:
    if value is None:
        return "z"
    kind = spec.kind
    if kind == "oneof":
        if isinstance(value, str) and value in spec.names:
            return f"e:{spec.names.index(value)}"
        assert spec.sub is not None
        return value_token(spec.sub, value)
    if kind == "enum":
        return f"e:{spec.names.index(value)}"
    if kind in NUMBER_KINDS:
        return number_token(value, spec.exp10)
    if kind in ("text", "ipv4", "literal"):
        return "t:" + value.encode("latin-1").hex()
    if kind == "raw":
        return "b:" + (value.hex() if isinstance(value, bytes) else str(value))
    if kind == "timestamp":
        return "d:" + value.strftime("%Y%m%d%H%M%S") + f"{value.microsecond // 10000:02d}"
    raise VectorError(f"no token for kind {kind}")


def _grid(spec: CodecSpec, m: int) -> Any:
    if not spec.pyfloat:
        return int(Decimal(m).scaleb(spec.exp10))
    return float(Decimal(m).scaleb(spec.exp10))


def random_sample(spec: CodecSpec, rnd: random.Random) -> Any:
    """A random valid value of a codec, in user units, with the fixed-point edges weighted in."""
    kind = spec.kind
    if kind in ("hexint", "decint", "binint", "decfloat"):
        if spec.none_tokens and rnd.random() < 0.1:
            return None
        lo, hi = spec.lo, spec.hi
        m = rnd.choice((lo, hi, lo + 1, hi - 1, 0, 1, -1, rnd.randint(lo, hi), rnd.randint(lo, hi)))
        return _grid(spec, min(max(m, lo), hi))
    if kind == "bitrate":
        return rnd.choice((spec.lo, spec.hi, 1000 * rnd.randint(1, 8), rnd.randint(spec.lo, spec.hi)))
    if kind in ("enum", "oneof"):
        if kind == "oneof" and spec.sub is not None and rnd.random() < 0.5:
            return random_sample(spec.sub, rnd)
        return rnd.choice(spec.names)
    if kind == "text":
        n = rnd.randint(spec.min_width, spec.max_width)
        return "".join(rnd.choice(_TEXT_CHARS) for _ in range(n))
    if kind == "ipv4":
        return ".".join(str(rnd.choice((0, 1, 9, 10, 99, 100, 255, rnd.randint(0, 255)))) for _ in range(4))
    if kind == "raw":
        n = spec.width if spec.width is not None else rnd.randint(spec.min_width, spec.max_width)
        allowed = range(256) if spec.binary else [b for b in range(256) if b not in b"#\r\n"]
        return bytes(rnd.choice(allowed) for _ in range(n))
    if kind in ("geodm", "geodeg"):
        lim = 90 if spec.lat else 180
        return rnd.choice((lim, -lim, 0.0, 1e-7, -1e-7, round(rnd.uniform(-lim, lim), 7), round(rnd.uniform(-1, 1), 7)))
    if kind == "timestamp":
        day = datetime(2000, 1, 1) + timedelta(seconds=rnd.randint(0, 100 * 365 * 86400 - 1))
        return day.replace(microsecond=10000 * rnd.randint(0, 99))
    return sample(spec, 0, rnd)


def sample(spec: CodecSpec, k: int, rnd: random.Random) -> Any:
    """The k-th sample value of a codec, in user units: 0 lowest, 1 highest, 2 random (the fixed
    three), any further k a random valid value with the edges weighted in."""
    if k > 2:
        return random_sample(spec, rnd)
    kind = spec.kind
    if kind in ("hexint", "decint", "binint", "decfloat"):
        if k == 2 and spec.none_tokens:
            return None
        lo, hi = spec.lo, spec.hi
        return _grid(spec, (lo, hi, rnd.randint(lo, hi))[k])
    if kind == "bitrate":
        return (spec.lo, 8000 if spec.lo <= 8000 <= spec.hi else spec.hi, rnd.randint(spec.lo, spec.hi))[k]
    if kind in ("enum", "oneof"):
        if kind == "oneof" and k == 2 and spec.sub is not None:
            return sample(spec.sub, 2, rnd)
        return spec.names[(k * 7 + rnd.randint(0, 99)) % len(spec.names)]
    if kind == "text":
        n = max(spec.min_width, min(spec.max_width, (6, spec.max_width, spec.min_width)[k]))
        return "".join(rnd.choice("ABCXYZ0123456789.-_ ") for _ in range(n))
    if kind == "ipv4":
        return ("10.1.2.3", "255.255.255.0", "0.0.0.0")[k]
    if kind == "raw":
        n = spec.width if spec.width is not None else max(spec.min_width, min(spec.max_width, (3, 0, 7)[k]))
        allowed = range(256) if spec.binary else [b for b in range(256) if b not in b"#\r\n"]
        return bytes(rnd.choice(allowed) for _ in range(n))
    if kind == "literal":
        return spec.text.decode("latin-1")
    if kind in ("geodm", "geodeg"):
        lim = 90 if spec.lat else 180
        return (round(rnd.uniform(-lim, lim), 6), -lim + 0.5, 0.25)[k]
    if kind == "timestamp":
        return (datetime(2024, 2, 29, 13, 45, 30, 120000), datetime(2000, 1, 1), datetime(2099, 12, 31, 23, 59, 59))[k]
    raise VectorError(f"no sample for kind {kind}")


def _frame_of(d: Dialect, spec: CommandSpec, form: Form, data: bytes) -> Frame:
    host = d.host_addresses[0]
    src, dst = (host, spec.address) if form.direction == REQUEST else (spec.address, host)
    header = d.header_for(spec, len(data), spec.address)
    return make_frame(spec.ident, data, src=src, dst=dst, rw=form.rw, header=header)


def _frame_tokens(f: Frame) -> str:
    declared = "-" if f.declared_length is None else str(f.declared_length)
    return f"F {HEADER[f.header]} {f.src}{f.dst}{f.rw or '-'} {f.ident} {f.data.hex() or '-'} {declared}"


def _events(stream: bytes, max_data: int, bytewise: bool) -> list[str]:
    p = PureFrameParser(max_data_length=max_data)
    out: list[Frame | Diagnostic] = []
    if bytewise:
        for i in range(len(stream)):
            out += p.feed(stream[i : i + 1])
    else:
        out += p.feed(stream)
    out += p.flush()
    return [_frame_tokens(e) if isinstance(e, Frame) else f"D {DIAG[e.kind]} {e.raw.hex() or '-'}" for e in out]


def _stream_block(name: str, stream: bytes, max_data: int) -> list[str] | None:
    whole = _events(stream, max_data, bytewise=False)
    if whole != _events(stream, max_data, bytewise=True):
        return None  # chunking-dependent by a checksum coincidence: not a good vector
    return [f"S {name} {stream.hex()}", *whole, "."]


def _garbage(rnd: random.Random) -> bytes:
    parts = [b"#", b"\r\n", b"#TP", b"#tpUG", b"xyz", bytes([rnd.randrange(256)]), b"#Tp", b"\x00"]
    return b"".join(rnd.choice(parts) for _ in range(rnd.randint(1, 5)))


def _corruptions(raw: bytes) -> list[bytes]:
    out = []
    crc = int(raw[-2:], 16)
    out.append(raw[:-2] + b"%02X" % ((crc + 1) & 0xFF))
    if raw[1:3] in (b"TP", b"tp"):
        n = int(raw[5:6], 16)
        for wrong in ((n + 3) % 16, (n - 3) % 16):
            bad = raw[:5] + b"%X" % wrong + raw[6:]
            # and the C12's quirk: a wrong length character inside a right checksum
            quirk = bad[:-2] + b"%02X" % (sum(bad[:-2]) & 0xFF)
            out += [bad, bad + b"\r\n" + raw, quirk, quirk + b"\r\n" + raw, quirk + raw]
    return out


def render(dialects: list[Dialect], max_data: int) -> str:
    rnd = random.Random(20240229)
    lines = ["# libtopgimbal test vectors (generated; see topgimbal/tools/cvectors.py)"]
    seen: set[str] = set()
    for d in dialects:  # frames no form takes: an unknown identifier, data of a length nothing takes
        for frame in (make_frame("ZZ9", b"00", src="U", dst="G"), make_frame("GAC", b"0", src="U", dst="G")):
            lines.append(_decode_line(d, None, frame))
    for d in dialects:
        for ci, spec in enumerate(d.commands.values()):
            for fi, form in enumerate(spec.forms):
                specs = [codec_spec(f.codec, f"{d.name} {spec.ident}.{f.name}") for f in form.fields]
                for k in range(3 + EXTRA_SAMPLES):
                    if k and not form.fields:
                        break
                    values: dict[str, Any] = {}
                    tokens = []
                    for f, cs in zip(form.fields, specs, strict=True):
                        if k == 1 and f.default is not None:
                            tokens.append("a")
                            continue
                        v = sample(cs, k, rnd)
                        try:  # canonical value: what decoding its own encoding gives
                            v = f.codec.decode(f.codec.encode(v, f.name))
                            tokens.append(value_token(cs, v))
                        except (TopGimbalError, ValueError, VectorError):
                            break
                        values[f.name] = v
                    else:
                        try:
                            data = form.encode(values, spec.ident)
                            frame = _frame_of(d, spec, form, data)
                        except TopGimbalError:
                            continue
                        raw = frame.to_bytes()
                        addr = f"{frame.src}{frame.dst}"
                        for line in (
                            f"N {d.name} {ci} {fi} {addr} {raw.hex()} {len(tokens)} {' '.join(tokens)}",
                            _decode_line(d, spec, frame),
                        ):
                            if line not in seen:
                                seen.add(line)
                                lines.append(line)
                        if k == 0:
                            lines += _streams(d, raw, max_data, rnd)
    return "\n".join(lines) + "\n"


def _decode_line(d: Dialect, spec: CommandSpec | None, frame: Frame) -> str:
    msg = d.decode(frame)
    spec = msg.spec
    raw = frame.to_bytes().hex()
    if msg.spec is None:
        return f"M {d.name} {raw} -6 - 0"
    if msg.form is None or msg.fields is None or spec is None:
        return f"M {d.name} {raw} -7 - 0"
    form = msg.form
    fi = next(i for i, f in enumerate(spec.forms) if f is form)
    tokens = [
        value_token(codec_spec(f.codec, f"{d.name} {spec.ident}.{f.name}"), msg.fields[f.name]) for f in form.fields
    ]
    return f"M {d.name} {raw} 0 {fi} {len(tokens)} {' '.join(tokens)}".rstrip()


def _streams(d: Dialect, raw: bytes, max_data: int, rnd: random.Random) -> list[str]:
    out: list[str] = []
    candidates = [raw, *_corruptions(raw)]
    for _ in range(4):
        candidates.append(_garbage(rnd) + raw + rnd.choice([b"", b"\r\n"]) + _garbage(rnd) + raw)
    for stream in candidates:
        block = _stream_block(d.name, stream, max_data)
        if block is not None:
            out += block
    return out
