"""Issue 34: `ConsoleConfig` and its parts check themselves, the keyword form and the CLI build the
same config, and `ConsoleServer` takes a config. Nothing here starts or binds anything."""

from __future__ import annotations

import dataclasses
import math
from typing import Any

import pytest

from topgimbal.cli.console_cmd import build_config
from topgimbal.cli.main import build_parser
from topgimbal.console import ConsoleServer
from topgimbal.console.config import (
    DEFAULT_MODEL,
    CameraSource,
    ConsoleConfig,
    ConsoleConfigError,
    FleetSource,
    LinkOptions,
    ProxySource,
    ServeOptions,
    SimSource,
)
from topgimbal.console.guard import HostNameError
from topgimbal.errors import AddressError, FieldValueError
from topgimbal.sim import FaultPlan

# The addresses are text the checks read; nothing is opened (the virtual tier's guard fails a test
# that binds or connects an IP socket).
pytestmark = pytest.mark.virtual

URL = "udp://127.0.0.1:9"
OTHER = "udp://127.0.0.1:10"


# -- each part checks itself --------------------------------------------------------------------

BAD_PARTS: list[tuple[Any, type[Exception], str]] = [
    (lambda: ServeOptions(port=70000), ConsoleConfigError, "--port 70000: give a port from 0 to 65535"),
    (lambda: ServeOptions(port=-1), ConsoleConfigError, "--port -1: give a port from 0 to 65535"),
    (lambda: ServeOptions(host=None), ConsoleConfigError, "--host None: give an address to listen on"),
    (lambda: ServeOptions(allow_hosts=("ok.example", "bad host")), HostNameError, "--allow-host"),
    (lambda: ServeOptions(allow_hosts="camera.example"), ConsoleConfigError, "give a list of names"),
    (lambda: LinkOptions(attitude_hz=0), FieldValueError, "attitude_hz=0 is not allowed: expected a rate above 0"),
    (lambda: LinkOptions(attitude_hz=math.nan), FieldValueError, "a rate above 0"),
    (lambda: LinkOptions(timeout_s=0), FieldValueError, "timeout_s=0 is not allowed: expected a number of seconds"),
    (lambda: LinkOptions(retries=-1), FieldValueError, "retries=-1 is not allowed: expected a whole number 0..100"),
    (lambda: LinkOptions(link_timeout_s=-3), FieldValueError, "link_timeout_s=-3"),
    (lambda: CameraSource(""), ConsoleConfigError, "give the camera's --url (and --model)"),
    (lambda: CameraSource("camera"), AddressError, "--url: device URL 'camera' must look like udp://HOST:PORT"),
    (lambda: CameraSource("udp://127.0.0.1"), AddressError, "--url: 'udp://127.0.0.1': a udp URL needs a host and a port"),
    (lambda: CameraSource(URL, "C99"), ConsoleConfigError, "--model 'C99' is not a device model; known: C10"),
    (lambda: CameraSource(URL, "C12", video_port=0), ConsoleConfigError, "--video-port 0: give a port from 1"),
    (lambda: CameraSource(URL, "C10", {"thermal": "rtsp://127.0.0.1/t"}), ConsoleConfigError,
     "the C10 has no lens 'thermal'; its lenses: visible"),
    (lambda: SimSource("C99"), ConsoleConfigError, "--sim 'C99' is not a device model"),
    (lambda: SimSource(""), ConsoleConfigError, "--sim: give a model name, e.g. C12"),
    (lambda: SimSource("C12", seed=1.5), ConsoleConfigError, "--seed 1.5: give a whole number"),
    (lambda: SimSource("C12", faults="silence=20-30"), ConsoleConfigError, "--faults: give a FaultPlan"),
    (lambda: ProxySource(URL, "", "C12"), ConsoleConfigError, "--proxy needs both --listen URL"),
    (lambda: ProxySource(URL, OTHER, ""), ConsoleConfigError, "give --model with --proxy"),
    (lambda: ProxySource("nowhere", OTHER, "C12"), AddressError, "--listen: device URL 'nowhere' must look like"),
    (lambda: ProxySource(URL, OTHER, "C99"), ConsoleConfigError, "--model 'C99' is not a device model"),
    (lambda: FleetSource(), ConsoleConfigError, "needs at least one --camera NAME=URL,MODEL, --sim MODEL or --zenoh"),
    (lambda: FleetSource(sims="C12"), ConsoleConfigError, "sims: give a list, not the text 'C12'"),
    (lambda: FleetSource(cameras=(("a", URL),)), ConsoleConfigError, "give each camera as (name, URL, model)"),
    (lambda: FleetSource(cameras=(("a", URL, "C99"),)), ConsoleConfigError, "--camera a 'C99' is not a device model"),
    (lambda: FleetSource(cameras=(("a", "nowhere", "C12"),)), AddressError, "--camera a: device URL 'nowhere'"),
    (lambda: FleetSource(sims=("C99",)), ConsoleConfigError, "--sim 'C99' is not a device model"),
    (lambda: FleetSource(zenoh=("tcp:127.0.0.1:7447",)), FieldValueError, "a Zenoh locator"),
    (lambda: ConsoleConfig("udp://127.0.0.1:9"), ConsoleConfigError,  # type: ignore[arg-type]
     "source: a CameraSource, SimSource, ProxySource or FleetSource, not str"),
    (lambda: ConsoleConfig(SimSource("C12"), serve=LinkOptions()), ConsoleConfigError,  # type: ignore[arg-type]
     "serve: a ServeOptions"),
]  # fmt: skip


@pytest.mark.parametrize(("make", "error", "message"), BAD_PARTS, ids=lambda v: v if isinstance(v, str) else "")
def test_each_part_refuses_what_cannot_work_saying_what_is_allowed(make: Any, error: type, message: str) -> None:
    with pytest.raises(error) as caught:
        make()
    assert message in str(caught.value)
    assert isinstance(caught.value, ValueError)  # every refusal is a ValueError (the CLI's usage errors)


def test_the_parts_are_frozen_and_hold_what_they_were_given() -> None:
    serve = ServeOptions(host="0.0.0.0", port=0, token="t", allow_hosts=["Camera.Example"])  # type: ignore[arg-type]
    assert serve.allow_hosts == ("Camera.Example",)  # a tuple: the config cannot change under the server
    with pytest.raises(dataclasses.FrozenInstanceError):
        serve.port = 1  # type: ignore[misc]
    cam = CameraSource(URL, "C12", {"visible": "rtsp://127.0.0.1/v"}, 8554)
    with pytest.raises(TypeError):
        cam.video_urls["thermal"] = "rtsp://127.0.0.1/t"  # type: ignore[index]
    assert CameraSource(URL).model == DEFAULT_MODEL == "C12"  # a URL without a model: as connect() has it
    fleet = FleetSource(cameras=[("sim1", URL, "C12")], sims=["SIP", "C12"], zenoh=["tcp/127.0.0.1:7447"])  # type: ignore[arg-type]
    assert fleet.plan == [("sim1", URL, "C12"), ("sim2", None, "SIP"), ("sim3", None, "C12")]
    assert fleet.zenoh == ("tcp/127.0.0.1:7447",)


# -- the keyword form and the CLI build the config ----------------------------------------------

PLAN = FaultPlan.parse("silence=20-30")
SAME_CONFIG: list[tuple[dict[str, Any], list[str], ConsoleConfig]] = [
    ({"sim_model": "C12"}, ["--sim", "C12"], ConsoleConfig(SimSource("C12"))),
    ({"sim_model": "C13", "sim_seed": 7, "sim_faults": PLAN, "port": 0},
     ["--sim", "C13", "--seed", "7", "--faults", "silence=20-30", "--port", "0"],
     ConsoleConfig(SimSource("C13", 7, PLAN), ServeOptions(port=0))),
    ({"url": URL, "model": "SIP", "host": "0.0.0.0", "token": "abc", "allow_hosts": ["bench.example"],
      "attitude_hz": 10.0},
     ["--url", URL, "--model", "sip", "--host", "0.0.0.0", "--token", "abc", "--allow-host", "bench.example",
      "--attitude-hz", "10"],
     ConsoleConfig(CameraSource(URL, "SIP"), ServeOptions("0.0.0.0", 8080, "abc", ("bench.example",)),
                   LinkOptions(attitude_hz=10.0))),
    ({"url": URL, "model": "C12", "video_urls": {"visible": "rtsp://127.0.0.1:8554/main"}, "video_port": 8555},
     ["--url", URL, "--model", "C12", "--video-url", "rtsp://127.0.0.1:8554/main", "--video-port", "8555"],
     ConsoleConfig(CameraSource(URL, "C12", {"visible": "rtsp://127.0.0.1:8554/main"}, 8555))),
    ({"proxy_listen": URL, "proxy_to": OTHER, "model": "C12"},
     ["--proxy", "--listen", URL, "--to", OTHER, "--model", "C12"],
     ConsoleConfig(ProxySource(URL, OTHER, "C12"))),
    ({"sims": ["C12", "SIP"], "sim_seed": 3}, ["--sim", "C12", "--sim", "SIP", "--seed", "3"],
     ConsoleConfig(FleetSource(sims=("C12", "SIP"), seed=3))),
    ({"cameras": [("left", URL, "C12")], "zenoh": ["tcp/127.0.0.1:7447"]},
     ["--camera", f"left={URL},C12", "--zenoh", "tcp/127.0.0.1:7447"],
     ConsoleConfig(FleetSource(cameras=(("left", URL, "C12"),), zenoh=("tcp/127.0.0.1:7447",)))),
]  # fmt: skip


@pytest.mark.parametrize(("keywords", "argv", "expected"), SAME_CONFIG, ids=lambda v: repr(v)[:40])
def test_the_keyword_form_and_the_cli_build_the_same_config(
    keywords: dict[str, Any], argv: list[str], expected: ConsoleConfig, monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.delenv("TOPGIMBAL_URL", raising=False)
    assert ConsoleConfig.from_keywords(**keywords) == expected
    assert ConsoleServer(**keywords).config == expected  # the keyword constructor: the same path
    assert build_config(build_parser().parse_args(["console", *argv])) == expected


def test_the_server_reads_its_config_as_the_keyword_form_did() -> None:
    sim = ConsoleServer.from_config(ConsoleConfig(SimSource("C13", 5), ServeOptions(port=0), LinkOptions(retries=4)))
    assert (sim.model, sim.sim_model, sim.sim_seed, sim.url, sim.multi) == ("C13", "C13", 5, None, False)
    assert (sim.port, sim.retries, sim.token, sim.video_urls, sim.video_port) == (0, 4, None, {}, None)
    cam = ConsoleServer(config=ConsoleConfig(CameraSource(URL, "SIP", {"visible": "rtsp://127.0.0.1/v"}, 9000)))
    assert (cam.url, cam.model, cam.sim_model, cam.video_port) == (URL, "SIP", None, 9000)
    assert cam.video_urls == {"visible": "rtsp://127.0.0.1/v"} and isinstance(cam.video_urls, dict)
    watch = ConsoleServer(proxy_listen=URL, proxy_to=OTHER, model="C12")
    assert (watch.proxy_listen, watch.proxy_to, watch.model, watch.url) == (URL, OTHER, "C12", None)
    fleet = ConsoleServer(sims=["C12"], zenoh=["tcp/127.0.0.1:7447"], model="SIP")  # a model is not used here
    assert fleet.multi and fleet.model is None and fleet.plan == [("sim1", None, "C12")]
    assert fleet.zenoh_endpoints == ("tcp/127.0.0.1:7447",)
    remote = ConsoleServer.from_config(ConsoleConfig(SimSource("C12"), ServeOptions(host="0.0.0.0")))
    assert remote.token and remote.token_generated  # resolved by the server: a config holds no secret it made


def test_config_and_keywords_are_one_or_the_other() -> None:
    with pytest.raises(TypeError, match="give config= or the keywords \\(port\\), not both"):
        ConsoleServer(config=ConsoleConfig(SimSource("C12")), port=0)
    with pytest.raises(TypeError, match="config= takes a ConsoleConfig, not SimSource"):
        ConsoleServer(config=SimSource("C12"))  # type: ignore[arg-type]
    with pytest.raises(TypeError, match="unexpected keyword\\(s\\): sim"):
        ConsoleServer(sim="C12")  # type: ignore[call-arg]


@pytest.mark.parametrize("port", ["70000", "-1", "http"])
def test_the_cli_refuses_a_port_out_of_range_before_probing_it(port: str, capsys: pytest.CaptureFixture[str]) -> None:
    with pytest.raises(SystemExit) as caught:
        build_parser().parse_args(["console", "--sim", "C12", "--port", port])
    assert caught.value.code == 2
    assert f"argument --port: '{port}': give a port from 0 to 65535 (0: any free port)" in capsys.readouterr().err
