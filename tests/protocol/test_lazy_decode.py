"""A one-frame decode builds only what it needs (issue 28: a CLI that starts fast), and gives the
same messages as the built decoders (the C fast path's when it is in use)."""

from __future__ import annotations

import subprocess
import sys

import pytest

from topgimbal.protocol import Dialect, decode_any, get_dialect, parse_frame
from topgimbal.protocol import dialects as dialects_mod
from topgimbal.protocol.dialects import ONE_OFF_FRAMES, _decode_any_py, any_decoder
from topgimbal.protocol.forms import REQUEST, Form
from topgimbal.protocol.frame import make_frame

from .real_world import frames

pytestmark = pytest.mark.loopback

# A fresh process (the memo of built dialects and decoders is per process): which dialects a
# decode builds, and whether it loads the C tables' builder.
PROBE = """
import sys
from topgimbal.protocol import decode_any, parse_frame
from topgimbal.protocol import dialects
msg = decode_any(parse_frame({frame!r}), prefer={prefer!r})
print(msg.dialect, msg.fields is not None)
print(' '.join(sorted(name for name, _options in dialects._built)))
print('topgimbal._speedups.spec' in sys.modules, 'topgimbal.protocol.parser' in sys.modules)
"""


def _probe(frame: bytes, prefer: str | None) -> list[str]:
    code = PROBE.format(frame=frame, prefer=prefer)
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120, check=True)
    return out.stdout.splitlines()


def test_a_frame_the_preferred_dialect_decodes_builds_that_dialect_alone() -> None:
    assert _probe(b"#TPUG6wGAYEC78324D", "skydroid") == ["skydroid True", "skydroid", "False False"]


def test_a_frame_the_preferred_dialect_cannot_decode_builds_the_others() -> None:
    # MOD (a SkyDroid camera's mode) is not in the TOPOTEK catalog: the SkyDroid dialect is built for it
    assert _probe(b"#TPUD2rMOD0044", "topotek") == ["skydroid True", "skydroid topotek", "False False"]


def test_without_a_preference_the_first_dialect_that_surely_ranks_first_decodes_alone() -> None:
    # the SkyDroid dialect has GAY, the #TP header and the host address U: no dialect can rank
    # above it (a tie keeps the default order), so the TOPOTEK dialect is not needed
    assert _probe(b"#TPUG6wGAYEC78324D", None) == ["skydroid True", "skydroid", "False False"]


def test_without_a_preference_a_frame_the_first_dialect_cannot_rank_first_builds_the_others() -> None:
    # GIA is TOPOTEK's: the SkyDroid dialect ranks below the TOPOTEK one, which must be built
    assert _probe(b"#TPUG2rGIA0038", None) == ["topotek True", "skydroid topotek", "False False"]


@pytest.mark.parametrize("prefer", [None, "skydroid", "topotek"])
def test_decode_any_gives_the_built_decoders_messages_before_and_after_it_builds_them(
    prefer: str | None, monkeypatch: pytest.MonkeyPatch
) -> None:
    """Real-world frames (some decoded by the other dialect, some by none) through decode_any from a
    fresh start: the first ONE_OFF_FRAMES in pure Python, the rest by `any_decoder`; every message
    equals the pure reference's and the built decoder's, error text included."""
    monkeypatch.setattr(dialects_mod, "_one_off", {})
    monkeypatch.setattr(dialects_mod, "_ANY_DECODERS", {})
    corpus = [f for _source, f in frames()]
    corpus += [make_frame("ZZZ", b"00"), make_frame("GAY", b"0", rw="r")]  # in no catalog; a length no form takes
    stream = (corpus * (2 * ONE_OFF_FRAMES // len(corpus) + 2))[: 2 * ONE_OFF_FRAMES]
    first = get_dialect(prefer) if prefer is not None else None
    defaults = [get_dialect(n) for n in dialects_mod.DIALECT_NAMES]
    key = prefer
    for i, frame in enumerate(stream):
        assert (key in dialects_mod._ANY_DECODERS) is (i > ONE_OFF_FRAMES), i
        got = decode_any(frame, prefer=prefer)
        want = _decode_any_py(frame, first, defaults, Dialect._decode_py)
        assert got == want and str(got.error) == str(want.error), frame.text()
    built = any_decoder(prefer)
    assert all(built(f) == decode_any(f, prefer=prefer) for f in corpus)
    assert {m.dialect for m in map(built, corpus)} >= {"skydroid", "topotek"}


def test_a_form_decodes_the_same_whether_its_decoder_is_built_by_decode_or_by_the_property() -> None:
    spec = get_dialect("skydroid").command("GAY")
    fields = next(f for f in spec.forms if f.direction == REQUEST and f.rw == "w").fields
    a, b = Form("w", REQUEST, fields), Form("w", REQUEST, fields)
    data = b"EC7832"
    assert a.decode(data) == b.decoder(data) == {"yaw_deg": -50.0, "speed_deg_s": 5.0}
    assert a == b and a.decoder is a.decoder
    with pytest.raises(ValueError, match="speed_deg_s"):
        b.decode(b"EC78ZZ")


def test_a_dialect_indexes_a_command_on_its_first_frame() -> None:
    sky = get_dialect("skydroid")
    d = Dialect("own", "a dialect of its own", sky.commands.values(), sky.models.values())
    assert not d._hot
    assert d._decode_py(parse_frame(b"#TPUG6wGAYEC78324D")).fields == {"yaw_deg": -50.0, "speed_deg_s": 5.0}
    assert set(d._hot) == {"GAY"}
    wrong = make_frame("PTZ", b"0000")  # PTZ takes 2 data bytes: the explained path indexes it too
    assert str(d._decode_explained(wrong).error) == str(sky.decode(wrong).error)
    assert set(d._hot) == {"GAY", "PTZ"}
