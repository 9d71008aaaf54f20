"""Differential fuzzer: the C streaming parser (ctypes-loaded build) against the Python
FrameParser on the same random streams, fed in the same chunks; they must agree event for event
(every frame and every diagnostic with its bytes) and on the statistics.

    python c/fuzz/diff_fuzz.py LIB.so [--seconds S] [--seed N]

Runs for a bounded time (or --iterations) and prints what it compared; exits 1 on the first
disagreement, printing a reproducer (seed, stream, chunking).
"""

from __future__ import annotations

import argparse
import ctypes
import random
import sys
import time
from typing import Any

from topgimbal.protocol import Frame, FrameParser, get_dialect, make_frame
from topgimbal.protocol.parser import PureFrameParser
from topgimbal.tools.cgen import limits
from topgimbal.tools.cvectors import DIAG, _frame_tokens

TOKENS = [
    b"#", b"#", b"#TP", b"#tp", b"#tP", b"#Tp", b"#T", b"#t", b"U", b"G", b"D", b"P", b"0", b"2", b"F",
    b"f", b"r", b"w", b"\r\n", b"\r", b"\n", b"\x00", b"\xff", b"GAC", b"G!C", b"#TPUD2wAWB0144",
    b"#tpDU3rVER0105025A", b"#TPUD", b"#tpUDF", b"#tPUD\xff", b"#TpUD\x00\x10",
]  # fmt: skip


class CParser:
    """The C streaming parser through c/fuzz/diff_shim.c."""

    def __init__(self, lib: Any, recover_length: bool, max_data: int) -> None:
        self.lib = lib
        self.mem = ctypes.create_string_buffer(lib.shim_size())
        lib.shim_init(self.mem, int(recover_length), max_data)
        self.out = ctypes.create_string_buffer(1 << 20)

    def feed(self, data: bytes, bytewise: bool, final: bool) -> list[str]:
        n = self.lib.shim_feed(self.mem, data, len(data), int(bytewise), int(final), self.out, len(self.out))
        if n < 0:
            raise RuntimeError(f"shim_feed failed ({n})")
        return self.out.raw[:n].decode("latin-1").splitlines()

    def stats(self) -> list[int]:
        arr = (ctypes.c_uint32 * 7)()
        self.lib.shim_stats(self.mem, arr)
        return list(arr)


def load(path: str) -> Any:
    lib = ctypes.CDLL(path)
    lib.shim_size.restype = ctypes.c_size_t
    lib.shim_init.argtypes = [ctypes.c_void_p, ctypes.c_uint, ctypes.c_uint]
    lib.shim_feed.argtypes = [
        ctypes.c_void_p, ctypes.c_char_p, ctypes.c_size_t, ctypes.c_int, ctypes.c_int, ctypes.c_char_p, ctypes.c_size_t,
    ]  # fmt: skip
    lib.shim_feed.restype = ctypes.c_int
    lib.shim_stats.argtypes = [ctypes.c_void_p, ctypes.POINTER(ctypes.c_uint32)]
    return lib


def python_events(parser: FrameParser, data: bytes, bytewise: bool, final: bool) -> list[str]:
    out: list[Any] = []
    if bytewise:
        for i in range(len(data)):
            out += parser.feed(data[i : i + 1])
    else:
        out += parser.feed(data)
    if final:
        out += parser.flush()
    return [_frame_tokens(e) if isinstance(e, Frame) else f"D {DIAG[e.kind]} {e.raw.hex() or '-'}" for e in out]


def sample_frames(rnd: random.Random) -> list[bytes]:
    """Good frames of both dialects, including binary data and every header."""
    frames = []
    for name in ("skydroid", "topotek"):
        d = get_dialect(name)
        for spec in d.commands.values():
            frames.append(make_frame(spec.ident, b"00", src="U", dst=spec.address).to_bytes())
    frames.append(b"#tpDU3rVER0105025A")
    for _ in range(40):
        data = bytes(rnd.randrange(256) for _ in range(rnd.randint(0, 40)))
        frames.append(make_frame("GPS", data, src="U", dst="G", header=rnd.choice(["#tP", "#Tp"])).to_bytes())
    return frames


def random_stream(rnd: random.Random, frames: list[bytes]) -> bytes:
    parts = []
    for _ in range(rnd.randint(1, 12)):
        r = rnd.random()
        if r < 0.45:
            f = bytearray(rnd.choice(frames))
            if rnd.random() < 0.3:  # corrupt a byte, cut it short, or lower-case the checksum
                k = rnd.randrange(len(f))
                choice = rnd.random()
                if choice < 0.4:
                    f[k] = rnd.randrange(256)
                elif choice < 0.7:
                    del f[k:]
                else:
                    f[-2:] = bytes(f[-2:]).lower()
            parts.append(bytes(f))
        elif r < 0.8:
            parts.append(rnd.choice(TOKENS))
        else:
            parts.append(bytes(rnd.randrange(256) for _ in range(rnd.randint(1, 8))))
    return b"".join(parts)


def chunks(rnd: random.Random, stream: bytes) -> list[tuple[bytes, bool, bool]]:
    """(piece, bytewise, final) plans: bytes, small chunks, datagrams."""
    mode = rnd.choice(["bytes", "chunks", "datagrams"])
    out = []
    i = 0
    while i < len(stream):
        n = 1 if mode == "bytes" else rnd.randint(1, 64)
        out.append((stream[i : i + n], mode == "bytes", mode == "datagrams"))
        i += n
    if out:
        piece, bw, _ = out[-1]
        out[-1] = (piece, bw, True)
    return out


def run(lib_path: str, seconds: float, seed: int, iterations: int | None = None) -> int:
    lib = load(lib_path)
    max_data = limits([get_dialect("skydroid"), get_dialect("topotek")])[0]
    rnd = random.Random(seed)
    frames = sample_frames(rnd)
    deadline = time.monotonic() + seconds
    n = events = 0
    while (iterations is None and time.monotonic() < deadline) or (iterations is not None and n < iterations):
        stream_seed = rnd.randrange(1 << 30)
        srnd = random.Random(stream_seed)
        stream = random_stream(srnd, frames)
        plan = chunks(srnd, stream)
        recover = srnd.random() < 0.9
        py = PureFrameParser(max_data_length=max_data, recover_length=recover)
        c = CParser(lib, recover, max_data)
        for piece, bytewise, final in plan:
            want = python_events(py, piece, bytewise, final)
            got = c.feed(piece, bytewise, final)
            events += len(want)
            pys = py.stats
            py_stats = [pys.frames, pys.bytes, pys.bad_checksums, pys.resyncs, pys.bytes_discarded,
                        pys.length_recoveries, pys.oversize]  # fmt: skip
            if got != want or c.stats() != py_stats:
                print(f"DISAGREE (seed {seed}, stream seed {stream_seed}, recover_length {recover})")
                print(f"stream: {stream!r}")
                print(f"plan: {[(len(p), b, f) for p, b, f in plan]}")
                print(f"piece: {piece!r}\npython: {want}\nC:      {got}")
                print(f"stats python {py_stats}\nstats C      {c.stats()}")
                return 1
        n += 1
    print(f"diff_fuzz: {n} streams, {events} events: the C and pure Python parsers agree")
    return 0


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("lib")
    ap.add_argument("--seconds", type=float, default=10.0)
    ap.add_argument("--iterations", type=int)
    ap.add_argument("--seed", type=int, default=int(time.time()))
    args = ap.parse_args()
    return run(args.lib, args.seconds, args.seed, args.iterations)


if __name__ == "__main__":
    sys.exit(main())
