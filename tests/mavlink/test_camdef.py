"""Camera definitions from the catalog: checked-in files current, accepted by MAVProxy's own parser
(1.8.75, `MAVProxy/modules/mavproxy_camera/definition.py`), true to each model's catalog; the
HTTP server that serves them bounded and safe with hostile input."""

from __future__ import annotations

import asyncio
from pathlib import Path

import pytest
from MAVProxy.modules.mavproxy_camera import definition  # installed by `make .venv/.installed`

from topgimbal.camdef.definition import all_definitions, definition_version, render, settings_for
from topgimbal.camdef.files import main as camdef_main
from topgimbal.camdef.files import stale
from topgimbal.camdef.http import MAX_CONNECTIONS, MAX_HEAD_BYTES, DefinitionServer
from topgimbal.protocol import get_model

from .conftest import eventually

pytestmark = pytest.mark.external

ROOT = Path(__file__).resolve().parents[2]


def test_checked_in_definitions_are_up_to_date(tmp_path: Path) -> None:
    assert stale(ROOT / "contrib" / "camera-definitions") == [], "run `make docs`"
    (tmp_path / "c12-visible.xml").write_text("old", encoding="utf-8")
    (tmp_path / "gone-visible.xml").write_text("old", encoding="utf-8")
    assert camdef_main(["--check", str(tmp_path)]) == 1
    assert camdef_main([str(tmp_path)]) == 0
    assert camdef_main(["--check", str(tmp_path)]) == 0
    assert not (tmp_path / "gone-visible.xml").exists()


@pytest.mark.parametrize("name", sorted(all_definitions()))
def test_mavproxy_parser_accepts_every_definition(name: str) -> None:
    text = all_definitions()[name]
    parsed = definition.CameraDefinition(text.encode("utf-8"), locale_name="en_US")
    model, lens = name[: -len(".xml")].rsplit("-", 1)
    d, m = get_model(model)
    settings = settings_for(d, m, lens)
    assert sorted(parsed.parameters) == sorted(s.param for s in settings) and settings
    assert parsed.version == str(definition_version(d, m, lens))
    for s in settings:
        p = parsed.parameters[s.param]
        assert p.wire_type == s.wire_type and p.default == (s.default if s.type == "float" else int(s.default))
        assert [v for _, v in p.options] == [o.value for o in s.options]
        if s.min is not None:
            assert (p.minimum, p.maximum) == (s.min, s.max)


def test_definitions_list_the_models_settings_per_lens() -> None:
    sip, sip_model = get_model("SIP")
    visible = {s.param for s in settings_for(sip, sip_model, "visible")}
    thermal = {s.param for s in settings_for(sip, sip_model, "thermal")}
    assert {"IMG_PALETTE", "TMR_RANGE"} <= thermal and not visible & thermal  # a thermal setting: thermal lens only
    assert {"PIP_MODE", "ROT_ROTATION", "BIT_BITRATE_KBPS"} <= visible
    c12, c12_model = get_model("C12")
    assert {"IMG_PALETTE", "TAS_INTERVAL_S"} == {s.param for s in settings_for(c12, c12_model, "thermal")}
    assert {"AWB_PRIMARY", "IQE_BRIGHTNESS", "VOM_FPS"} <= {s.param for s in settings_for(c12, c12_model, "visible")}
    c10, c10_model = get_model("C10")
    assert settings_for(c10, c10_model, "thermal") == []  # no thermal lens, no thermal file
    assert "c10-thermal.xml" not in all_definitions()


def test_palette_options_are_the_catalogs_with_the_vendors_terms() -> None:
    d, m = get_model("C12")
    palette = next(s for s in settings_for(d, m, "thermal") if s.param == "IMG_PALETTE")
    names = [o.name for o in palette.options]
    assert "next" not in names and "previous" not in names  # steps are not values
    assert palette.option(4) is not None and palette.option(4).name == "ironbow"  # type: ignore[union-attr]
    zh = definition.CameraDefinition(render(d, m, "thermal").encode(), locale_name="zh_CN")
    assert ("铁红", 4) in zh.parameters["IMG_PALETTE"].options
    en = definition.CameraDefinition(render(d, m, "thermal").encode(), locale_name="en_US")
    assert ("Ironbow", 4) in en.parameters["IMG_PALETTE"].options


def test_setting_values_are_checked() -> None:
    d, m = get_model("SIP")
    by = {s.param: s for s in settings_for(d, m, "visible")}
    with pytest.raises(ValueError, match="not an option"):
        by["ROT_ROTATION"].to_api(1)  # 0° and 180° only
    with pytest.raises(ValueError, match="out of"):
        by["BIT_BITRATE_KBPS"].to_api(10)
    with pytest.raises(ValueError, match="whole"):
        by["BIT_BITRATE_KBPS"].to_api(100.5)
    assert by["BIT_BITRATE_KBPS"].to_api(2000.0) == 2000


async def _http(port: int, data: bytes, read: bool = True) -> bytes:
    reader, writer = await asyncio.open_connection("127.0.0.1", port)
    writer.write(data)
    await writer.drain()
    out = await asyncio.wait_for(reader.read(), 10) if read else b""
    writer.close()
    return out


async def test_http_server_serves_only_its_files_and_survives_hostile_requests() -> None:
    text = all_definitions()["sip-thermal.xml"]
    server = DefinitionServer({"sip-thermal.xml": text})
    await server.start()
    try:
        ok = await _http(server.port, b"GET /sip-thermal.xml HTTP/1.1\r\nHost: x\r\n\r\n")
        assert ok.startswith(b"HTTP/1.1 200") and ok.endswith(text.encode())
        head = await _http(server.port, b"HEAD /sip-thermal.xml HTTP/1.1\r\n\r\n")
        assert head.startswith(b"HTTP/1.1 200") and head.endswith(b"\r\n\r\n")
        assert (await _http(server.port, b"GET /../etc/passwd HTTP/1.1\r\n\r\n")).startswith(b"HTTP/1.1 404")
        assert (await _http(server.port, b"POST /sip-thermal.xml HTTP/1.1\r\n\r\n")).startswith(b"HTTP/1.1 405")
        assert (await _http(server.port, b"\xff\xfe garbage\r\n\r\n")).startswith(b"HTTP/1.1 400")
        huge = b"GET /" + b"a" * (MAX_HEAD_BYTES * 2) + b" HTTP/1.1\r\n\r\n"
        assert (await _http(server.port, huge)).startswith(b"HTTP/1.1 400")
        # more idle connections than allowed: the extra ones are closed, the server still answers after
        idle = [await asyncio.open_connection("127.0.0.1", server.port) for _ in range(MAX_CONNECTIONS + 3)]
        await eventually(lambda: server.refused >= 3, 5, "the extra idle connections refused")
        for _, w in idle:
            w.close()
        await eventually(lambda: server.active == 0, 5, "the idle connections' closes noticed")
        assert (await _http(server.port, b"GET /sip-thermal.xml HTTP/1.0\r\n\r\n")).startswith(b"HTTP/1.1 200")
        assert server.uri("sip-thermal.xml") == f"http://127.0.0.1:{server.port}/sip-thermal.xml"
    finally:
        await server.close()


def test_cli_names_the_definitions_and_checks_the_option(capsys: pytest.CaptureFixture[str]) -> None:
    from topgimbal.cli.main import main
    from topgimbal.sim import BackgroundSimulator

    base = ["mavlink", "--model", "SIP", "--mavlink", "udpin:127.0.0.1:0", "--seconds", "0.5"]
    with BackgroundSimulator("SIP", listen={"udp": [("127.0.0.1", 0)]}) as sim:
        assert main([*base, "--url", sim.url]) == 0
        out = capsys.readouterr().out
        assert "camera 101 definition: http://127.0.0.1:" in out and out.rstrip().endswith("/sip-thermal.xml")
        assert main([*base, "--url", sim.url, "--definition-http", "off"]) == 0
        assert "camera 100 definition: mftp://[;comp=100]/sip-visible.xml" in capsys.readouterr().out
    assert main([*base, "--url", "udp://127.0.0.1:9", "--definition-http", "nowhere"]) != 0
    assert "error: --definition-http='nowhere': expected HOST:PORT" in capsys.readouterr().err  # told with the flag
