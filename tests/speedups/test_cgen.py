"""The C tables are generated from the catalog: current, and the generator fails loudly on what
it cannot express."""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import pytest

from topgimbal._speedups.spec import CodecSpecError, codec_spec
from topgimbal.protocol.fields import Codec, HexInt
from topgimbal.tools import cgen

pytestmark = pytest.mark.virtual


def test_generated_tables_are_current() -> None:
    assert cgen.main(["--check"]) == 0


def test_check_names_stale_files(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    assert cgen.main(["--out", str(tmp_path)]) == 0
    assert cgen.main(["--check", "--out", str(tmp_path)]) == 0
    (tmp_path / "tg_catalog.c").write_text("/* edited by hand */\n")
    capsys.readouterr()
    assert cgen.main(["--check", "--out", str(tmp_path)]) == 1
    assert "tg_catalog.c" in capsys.readouterr().err


@dataclass(frozen=True)
class Morse(Codec):
    """A codec kind the C core has never heard of."""

    width: int = 4
    kind: str = "morse"


def test_unknown_codec_kind_fails_loudly() -> None:
    with pytest.raises(CodecSpecError, match=r"GAY\.yaw_deg: codec class 'Morse' \(kind 'morse'\) is not known"):
        codec_spec(Morse(), "GAY.yaw_deg")


def test_a_scale_the_c_core_would_round_fails_loudly() -> None:
    # DecInt keeps round(v * 0.25, 1): one decimal; the fixed-point value would keep two.
    from topgimbal.protocol.fields import DecInt

    with pytest.raises(CodecSpecError, match="more decimals"):
        codec_spec(DecInt(2, scale=0.25), "X.y")
    assert codec_spec(HexInt(2, scale=0.25), "X.y").exp10 == -2  # HexInt divides exactly: fine


def test_generator_reports_an_unknown_kind_in_the_catalog(
    monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    from topgimbal._speedups import spec

    monkeypatch.delitem(spec.HANDLERS, "Bitrate")
    assert cgen.main(["--check"]) == 2
    assert "codec class 'Bitrate'" in capsys.readouterr().err


def test_fixed_point_descriptors_hold_the_catalog_values() -> None:
    s = codec_spec(HexInt(4, signed=True, scale=0.01, min=-90, max=90))
    assert (s.exp10, s.mul, s.lo, s.hi, s.pyfloat) == (-2, 1, -9000, 9000, True)
    s = codec_spec(HexInt(2, signed=True, scale=0.1, min=-12.700000000000001, max=12.700000000000001))
    assert (s.lo, s.hi) == (-127, 127)  # the float's last-digit noise does not shift the bounds
