"""Issue 34: a console built from a `ConsoleConfig` starts and serves like the keyword form, and a
mode that fails half-way leaves nothing running (modes.py cleans up what it had started)."""

from __future__ import annotations

import aiohttp
import pytest

from topgimbal import client
from topgimbal.console import ConsoleServer
from topgimbal.console.config import ConsoleConfig, LinkOptions, ServeOptions, SimSource
from topgimbal.sim import Simulator

pytestmark = pytest.mark.loopback


async def test_a_console_from_a_config_serves_its_simulator() -> None:
    config = ConsoleConfig(SimSource("SIP", seed=3), ServeOptions(port=0, token="s3cret"), LinkOptions(attitude_hz=5))
    async with ConsoleServer.from_config(config) as srv, aiohttp.ClientSession() as http:
        assert srv.sim is not None and srv.url == srv.sim.url and srv.url.startswith("udp://127.0.0.1:")
        async with http.get(srv.base_url + "api/status", params={"token": "s3cret"}) as r:
            assert r.status == 200
        async with http.get(srv.base_url + "api/status") as r:
            assert r.status == 401  # the config's token is enforced
        assert "SIP at udp://127.0.0.1:" in srv.banner()
    assert srv.sim is None and srv.cam is None and srv.hub is None


async def test_a_simulator_whose_client_fails_is_stopped(monkeypatch: pytest.MonkeyPatch) -> None:
    stopped: list[Simulator] = []
    real_stop = Simulator.stop

    async def stop(self: Simulator) -> None:
        stopped.append(self)
        await real_stop(self)

    async def refuse(*args: object, **kwargs: object) -> None:
        raise OSError("the client could not open its socket")

    monkeypatch.setattr(Simulator, "stop", stop)
    monkeypatch.setattr(client, "connect", refuse)
    srv = ConsoleServer.from_config(ConsoleConfig(SimSource("C12"), ServeOptions(port=0)))
    with pytest.raises(OSError, match="could not open its socket"):
        await srv.start()
    assert len(stopped) == 1  # the simulator modes.open_sim had started
    assert srv.sim is None and srv.app is None and srv.bound_port is None
