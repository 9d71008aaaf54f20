"""Issue 34: every mixture of the console's forms that was refused before `ConsoleConfig` is still
refused, with the same words, through the keyword form (`ConsoleServer(url=..., ...)`) and the CLI
(`topgimbal console ...`). Deciding needs no socket: nothing here starts or binds anything."""

from __future__ import annotations

import argparse
from typing import Any

import pytest

from topgimbal.cli.console_cmd import build_server
from topgimbal.cli.main import build_parser
from topgimbal.console import ConsoleServer
from topgimbal.sim import FaultPlan

# The addresses below are text the checks read; nothing is opened (the virtual tier's guard fails
# a test that binds or connects an IP socket).
pytestmark = pytest.mark.virtual

URL = "udp://127.0.0.1:9"
FAULTS = FaultPlan.parse("silence=20-30")
NO_SOURCE = "give the camera's --url (and --model), or --sim MODEL to run a simulator"
BOTH = "--proxy needs both --listen URL (where clients connect) and --to URL (the camera)"
BEHIND = "--proxy watches the camera behind it: give --listen and --to, not --url or --sim"
PROXY_MODEL = "give --model with --proxy: the page describes the camera's commands from its model"
VIDEO = "--video-url and --video-port are for a camera given with --url"
FLEET = "cannot be combined with --camera, several --sim or --zenoh: give every camera with --camera NAME=URL,MODEL"

# (keywords, what the refusal says): the old constructor's checks, in its order.
KEYWORD_REFUSALS: list[tuple[dict[str, Any], str | None]] = [
    ({}, NO_SOURCE),
    ({"model": "C12"}, NO_SOURCE),
    ({"sim_faults": FAULTS}, NO_SOURCE),
    ({"url": URL, "sim_model": "C12"}, "--sim runs its own simulator: give either --url or --sim, not both"),
    ({"url": URL, "sim_model": "C12", "sim_faults": FAULTS}, "give either --url or --sim, not both"),
    ({"proxy_listen": URL, "model": "C12"}, BOTH),
    ({"proxy_to": URL, "model": "C12"}, BOTH),
    ({"proxy_listen": "", "proxy_to": "", "model": "C12"}, BOTH),
    ({"proxy_listen": URL, "sim_model": "C12"}, BOTH),
    ({"proxy_listen": URL, "proxy_to": URL, "sim_model": "C12", "model": "C12"}, BEHIND),
    ({"proxy_listen": URL, "proxy_to": URL, "url": URL, "model": "C12"}, BEHIND),
    ({"proxy_listen": URL, "proxy_to": URL}, PROXY_MODEL),
    ({"proxy_listen": URL, "proxy_to": URL, "model": "C12", "sim_faults": FAULTS}, "--faults applies to the simulator"),
    ({"url": URL, "model": "C12", "sim_faults": FAULTS}, "--faults applies to the simulator: use it with --sim"),
    ({"sim_model": "C12", "video_urls": {"visible": "rtsp://127.0.0.1/x"}}, VIDEO),
    ({"sim_model": "C12", "video_port": 8554}, VIDEO),
    ({"proxy_listen": URL, "proxy_to": URL, "model": "C12", "video_port": 8554}, VIDEO),
    ({"url": URL, "model": "C12", "video_port": 70000}, "--video-port 70000: give a port from 1 to 65535"),
    ({"url": URL, "model": "C12", "video_port": 0}, "--video-port 0: give a port from 1 to 65535"),
    ({"url": URL, "model": "C12", "video_urls": {"bogus": "rtsp://127.0.0.1/x"}},
     "has no lens 'bogus'; its lenses: visible, thermal"),
    ({"url": URL, "model": "C12", "video_urls": {"visible": "ftp://127.0.0.1/x"}},
     "expected a stream URL such as rtsp://HOST:PORT/PATH"),
    ({"sims": ["C12"], "url": URL}, f"--url {FLEET}"),
    ({"sims": ["C12", "SIP"], "sim_model": "C12"}, f"--sim MODEL (alone) {FLEET}"),
    ({"zenoh": ["tcp/127.0.0.1:7447"], "proxy_listen": URL, "proxy_to": URL}, f"--proxy {FLEET}"),
    ({"cameras": [("a", URL, "C12")], "sim_faults": FAULTS}, f"--faults {FLEET}"),
    ({"sims": ["C12"], "video_urls": {"visible": "rtsp://127.0.0.1/x"}, "video_port": 8554},
     f"--video-url, --video-port {FLEET}"),
    ({"cameras": [("bad name", URL, "C12")]}, "camera name 'bad name': 1..63 letters"),
    ({"cameras": [("a", URL, "C12"), ("a", URL, "SIP")]}, "camera name 'a' is given twice"),
    ({"cameras": [("sim1", URL, "C12")], "sims": ["C12"]}, None),  # accepted: the simulator is sim2
    ({"sims": ["C12"] * 65}, "65 cameras given: a console shows at most 64"),
    ({"zenoh": ["nope"]}, "expected a Zenoh locator such as tcp/127.0.0.1:7447"),
    ({"sim_model": "C12", "allow_hosts": ["bad host"]}, "--allow-host"),
]  # fmt: skip


@pytest.mark.parametrize(("keywords", "message"), KEYWORD_REFUSALS, ids=lambda v: repr(v)[:60])
def test_the_keyword_form_refuses_what_it_refused(keywords: dict[str, Any], message: str | None) -> None:
    if message is None:
        ConsoleServer(**keywords)
        return
    with pytest.raises(ValueError) as caught:
        ConsoleServer(**keywords)
    assert message in str(caught.value)


def _args(argv: list[str]) -> argparse.Namespace:
    return build_parser().parse_args(["console", *argv])


CLI_FLEET = "cannot be combined with --camera, --cameras, several --sim or --zenoh: give every camera with"

# (the flags after `console`, what the refusal says): the CLI's own checks, then the config's.
CLI_REFUSALS: list[tuple[list[str], str]] = [
    ([], NO_SOURCE),
    (["--seed", "3"], NO_SOURCE),
    (["--faults", "silence=20-30"], NO_SOURCE),
    (["--url", URL], "give --model with --url (it picks the dialect), e.g. --model SIP"),
    (["--url", URL, "--model", "C12", "--sim", "C12"], "--sim runs its own simulator: give either --url or --sim"),
    (["--listen", URL, "--to", URL], "--listen and --to go with --proxy"),
    (["--to", URL], "--listen and --to go with --proxy"),
    (["--proxy", "--sim", "C12"], "--proxy watches the camera behind it: give --listen and --to, not --sim"),
    (["--proxy", "--listen", URL, "--model", "C12"], BOTH),
    (["--proxy"], BOTH),
    (["--proxy", "--listen", URL, "--to", URL], PROXY_MODEL),
    (["--url", URL, "--model", "C12", "--faults", "silence=20-30"], "--faults applies to the simulator"),
    (["--sim", "C12", "--video-port", "8554"], "are for a camera given with --url"),
    (["--url", URL, "--model", "C12", "--video-port", "70000"], "give a port from 1 to 65535"),
    (["--url", URL, "--model", "C12", "--video-url", "bogus=rtsp://127.0.0.1/x"], "has no lens 'bogus'"),
    (["--sim", "C12", "--sim", "SIP", "--url", URL], f"--url {CLI_FLEET}"),
    (["--camera", f"a={URL},C12", "--faults", "silence=20-30"], f"--faults {CLI_FLEET}"),
    (["--zenoh", "tcp/127.0.0.1:7447", "--proxy"], f"--proxy {CLI_FLEET}"),
    (["--camera", f"a={URL},C12", "--video-port", "8554"], f"--video-port {CLI_FLEET}"),
    (["--camera", f"a={URL},C12", "--camera", f"a={URL},SIP"], "camera name 'a' is given twice"),
    (["--zenoh", "nope"], "expected a Zenoh locator"),
    (["--sim", "C12", "--allow-host", "bad host"], "--allow-host"),
]  # fmt: skip


@pytest.mark.parametrize(("argv", "message"), CLI_REFUSALS, ids=lambda v: " ".join(v) if isinstance(v, list) else "")
def test_the_cli_refuses_what_it_refused(argv: list[str], message: str, monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.delenv("TOPGIMBAL_URL", raising=False)  # the main parser's --url default
    with pytest.raises(ValueError) as caught:
        build_server(_args(argv))
    assert message in str(caught.value)
