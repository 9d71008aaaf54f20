"""What a frame no form takes costs to decode, against one that decodes (issue 26, item 2), and the
share of valid real-world frames decoded with meaning (item 1).

    python bench/decode_failures.py [--rounds R] [--number N] [--tree DIR]

Each frame is decoded N times with `any_decoder()` (what `decode`, the proxy and the console use)
and with its dialect's `decode`; the figure is microseconds per frame, best of R rounds (CPU time,
time.process_time; the machine is shared, the load average is printed). The errors are not read
(a capture decodes every frame, few errors are ever shown). `--tree DIR`: measure the source tree
DIR/src instead (e.g. an older commit from `git archive`), with the same frames. Prints figures;
asserts nothing.
"""

from __future__ import annotations

import argparse
import os
import subprocess
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "tests" / "protocol"))

CASES = {
    "known: GAC answer (SkyDroid)": "#TPGUCrGACFF36ED5A0048",
    "known: PTZ write (TOPOTEK)": "#TPUG2wPTZ05",
    "unknown identifier": "#TPUD2wXYZ01",
    "a code no table has (PTZ 7F)": "#TPUG2wPTZ7F",
    "a length no form takes (GAY, 3)": "#tpUG3wGAY123",
    "DZM, 6 characters no form takes": "#tpUD6wDZM0AG08C",
    "DZM image code + F + hex ratio": "#tpPD6wDZM03F08C",
    "SLR fire (2 characters)": "#TPUD2wSLR01",
}


def load() -> str:
    one, five, fifteen = os.getloadavg()
    return f"load average {one:.2f} {five:.2f} {fifteen:.2f} on {os.cpu_count()} CPUs"


def measure(rounds: int, number: int) -> None:
    from real_world import meaning_share, with_crc, without_meaning

    from topgimbal.protocol import any_decoder, decode_any, parse_frame

    dec = any_decoder()
    share = meaning_share()
    print(f"real-world frames decoded with meaning: {share * 100:.1f} % ({len(without_meaning())} without)")
    print(f"{'frame':36s} {'any_decoder us':>15s} {'dialect us':>11s}  decoded")
    for name, text in CASES.items():
        frame = parse_frame(with_crc(text))
        msg = decode_any(frame)
        one = msg.dialect or "skydroid"
        from topgimbal.protocol import get_dialect

        dialect = get_dialect(one)
        best_any = best_one = float("inf")
        for _ in range(rounds):
            t0 = time.process_time()
            for _ in range(number):
                dec(frame)
            best_any = min(best_any, (time.process_time() - t0) / number)
            t0 = time.process_time()
            for _ in range(number):
                dialect.decode(frame)
            best_one = min(best_one, (time.process_time() - t0) / number)
        print(f"{name:36s} {best_any * 1e6:15.2f} {best_one * 1e6:11.2f}  {'yes' if msg.fields is not None else 'no'}")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--rounds", type=int, default=5)
    ap.add_argument("--number", type=int, default=5000)
    ap.add_argument("--tree", type=Path, help="measure DIR/src instead of this checkout")
    args = ap.parse_args()
    print(load())
    if args.tree is not None:
        env = {**os.environ, "PYTHONPATH": f"{args.tree.resolve() / 'src'}"}
        argv = [sys.executable, __file__, "--rounds", str(args.rounds), "--number", str(args.number)]
        subprocess.run(argv, env=env, check=True)
        return
    import topgimbal

    print(f"tree: {Path(topgimbal.__file__).parents[2]}")
    measure(args.rounds, args.number)


if __name__ == "__main__":
    main()
