"""`topgimbal mavlink`'s flags to BridgeConfig, generated from the fields (issue 44): each field
that names a flag is filled from it, every flag of the command is either a field's or one the
command uses itself, errors name the flag the user typed, and the attached features bring their
own flags. Pure: no socket (argparse and dataclasses only)."""

from __future__ import annotations

import dataclasses

import pytest

from topgimbal.cli.config_args import config_kwargs, flag_dest, flags_of, with_flags
from topgimbal.cli.main import build_parser
from topgimbal.cli.mavlink_cmd import build_config
from topgimbal.errors import InputError
from topgimbal.mavlink.bridge_config import BridgeConfig
from topgimbal.mavlink.features import FEATURES

pytestmark = pytest.mark.virtual

BASE = ["mavlink", "--url", "udp://127.0.0.1:5000", "--model", "C12", "--mavlink", "udpin:127.0.0.1:0"]
# flags of `topgimbal mavlink` that are not BridgeConfig fields: the command's own
COMMAND_ONLY = {"url", "model", "camera", "help", "verbose", "seconds", "json", "status_every", "status_json",
                "no_camera", "cot_key", "cot_ca", "cot_server_name", "dialect", "status"}  # fmt: skip


def parse(*argv: str):  # type: ignore[no-untyped-def]
    return build_parser().parse_args([*BASE, *argv])


def test_defaults_from_no_flags_are_the_dataclass_defaults() -> None:
    built = build_config(parse())
    plain = BridgeConfig(url="udp://127.0.0.1:5000", model="C12", endpoints=["udpin:127.0.0.1:0"])
    assert built == plain


def test_every_flag_lands_in_its_field(tmp_path) -> None:  # type: ignore[no-untyped-def]
    key = tmp_path / "key"
    key.write_text("a" * 64)
    built = build_config(parse(
        "--sysid", "7", "--compid", "171", "--camera-compid", "102", "--no-thermal", "--role", "device",
        "--attitude-hz", "10", "--stream-hz", "25", "--range-hz", "0", "--video-url", "rtsp://127.0.0.1:8554/a",
        "--video-port", "9554", "--media-url", "http://127.0.0.1:8080/", "--timeout", "2", "--silence", "5",
        "--max-peers", "8", "--signing-key", str(key), "--definition-http", "off", "--definition-host", "127.0.0.1",
        "--no-request-streams", "--record", str(tmp_path / "rec"), "--companion-tracking",
    ))  # fmt: skip
    assert isinstance(built, BridgeConfig)
    assert (built.sysid, built.compid, built.camera_compid, built.thermal, built.role) == (7, 171, 102, False, "device")
    assert (built.attitude_hz, built.stream_hz, built.range_hz, built.timeout_s, built.silence_s) == (10, 25, 0, 2, 5)
    assert built.video_urls == ["rtsp://127.0.0.1:8554/a"] and built.video_port == 9554
    assert (
        built.media_url == "http://127.0.0.1:8080/"
        and built.max_peers == 8
        and built.signing_key == bytes.fromhex("a" * 64)
    )
    assert built.definition_http is None and built.definition_host == "127.0.0.1" and built.request_streams is False
    assert built.record == str(tmp_path / "rec") and built.companion_tracking is True
    assert build_config(parse("--no-camera")).camera_compid is None  # type: ignore[attr-defined]


def test_every_flag_of_the_command_is_a_field_or_the_commands_own() -> None:
    """A flag added to `topgimbal mavlink` with no field naming it would be parsed and dropped."""
    parser = build_parser()
    sub = next(a for a in parser._subparsers._actions if a.choices and "mavlink" in a.choices).choices["mavlink"]  # type: ignore[union-attr]
    dests = {a.dest for a in sub._actions}
    fields = {flag_dest(f) for f in flags_of(BridgeConfig).values()}
    stray = dests - fields - COMMAND_ONLY
    assert not stray, f"flags of `topgimbal mavlink` that no BridgeConfig field takes: {sorted(stray)}"
    missing = fields - dests
    assert not missing, f"BridgeConfig fields naming flags the command does not have: {sorted(missing)}"


def test_each_feature_brings_its_own_flags() -> None:
    import argparse

    for spec in FEATURES:
        p = argparse.ArgumentParser()
        spec.add_arguments(p)
        mine = {a.dest for a in p._actions} - {"help"}
        assert mine and mine <= {flag_dest(f) for f in flags_of(BridgeConfig).values()} | COMMAND_ONLY, spec.name


def test_errors_name_the_flag_the_user_typed(tmp_path) -> None:  # type: ignore[no-untyped-def]
    with pytest.raises(InputError, match=r"^--max-peers=300: expected 1\.\.256$"):
        build_config(parse("--max-peers", "300"))
    a_file = tmp_path / "f"
    a_file.write_text("")
    with pytest.raises(InputError, match=rf"^--record {a_file}: not a directory"):
        build_config(parse("--record", str(a_file)))
    assert with_flags("stream_hz=0: expected 1..100", BridgeConfig) == "--stream-hz=0: expected 1..100"
    assert with_flags("system id 0: expected 1..255", BridgeConfig) == "system id 0: expected 1..255"
    assert with_flags("retries=9: no flag", BridgeConfig) == "retries=9: no flag"  # a field without one


def test_a_field_whose_flag_the_parser_lacks_keeps_its_default() -> None:
    import argparse

    got = config_kwargs(BridgeConfig, argparse.Namespace(sysid=3))
    assert got["sysid"] == 3 and "attitude_hz" not in got
    assert {f.name for f in dataclasses.fields(BridgeConfig)} >= set(got)
