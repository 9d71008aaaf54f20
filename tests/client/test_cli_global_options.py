"""`--url` and `--model` work before or after the command (a new user writes `topgimbal proxy
--model C12 ...` as the docs' synopsis reads)."""

from __future__ import annotations

import pytest

from topgimbal.cli.main import build_parser

pytestmark = pytest.mark.loopback


@pytest.mark.parametrize(
    "argv, url, model",
    [
        (["--url", "udp://127.0.0.1:1", "--model", "SIP", "info"], "udp://127.0.0.1:1", "SIP"),
        (["info", "--url", "udp://127.0.0.1:1", "--model", "sip"], "udp://127.0.0.1:1", "SIP"),
        (["--model", "C12", "info", "--model", "C13"], None, "C13"),  # after the command wins
        (["--model", "C12", "info"], None, "C12"),  # not given after: the global value stays
    ],
)
def test_url_and_model_before_or_after_the_command(
    argv: list[str], url: str | None, model: str, monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.delenv("TOPGIMBAL_URL", raising=False)
    monkeypatch.delenv("TOPGIMBAL_MODEL", raising=False)
    args = build_parser().parse_args(argv)
    assert (args.url, args.model) == (url, model)


def test_proxy_takes_the_model_after_the_command() -> None:
    args = build_parser().parse_args(
        ["proxy", "--model", "C12", "--listen", "udp://127.0.0.1:0", "--to", "udp://127.0.0.1:9"]
    )
    assert args.model == "C12" and args.command == "proxy"


@pytest.mark.virtual
def test_a_wrong_model_after_the_command_lists_the_models(capsys: pytest.CaptureFixture[str]) -> None:
    with pytest.raises(SystemExit) as exc:
        build_parser().parse_args(["info", "--model", "C99"])
    assert exc.value.code == 2
    err = capsys.readouterr().err
    assert "C99" in err and "C12" in err and "SIP" in err


@pytest.mark.virtual
def test_commands_with_their_own_model_option_keep_it() -> None:
    args = build_parser().parse_args(["sim", "--model", "SIP"])
    assert args.sim_model == "SIP"
