"""Issue 33, items 1-6: only the operator acts on a served camera. Each test attacks the server the
way the hostile-peer sweep did (an independent eclipse-zenoh session, none of our client code
unless it is the operator's) and checks the refusal and that the operator still works."""

from __future__ import annotations

import asyncio
import contextlib
import json
import logging
import sys
import threading
from pathlib import Path
from typing import Any

import pytest

import topgimbal
from topgimbal.client.remote_keys import RemoteCallError
from topgimbal.client.zenoh_session import make_config, zenoh_error_text
from topgimbal.fleet import CameraSpec, FleetServer
from topgimbal.fleet import camera as camera_mod
from topgimbal.fleet import server as server_mod
from topgimbal.fleet.access import AccessConfigError, check_allowed, check_exposure, is_loopback
from topgimbal.fleet.server import DuplicateCameraError
from topgimbal.links import json_shape
from topgimbal.links.zenoh_link import ZenohLink
from waiting import SETTLED_DEG, near, until

from .conftest import eventually, free_port, raw_call, raw_session

pytestmark = [pytest.mark.loopback, pytest.mark.integration]

ACL = """{
  transport: { auth: { usrpwd: { user: "server", password: "srv-pass", dictionary_file: "DICT" } } },
  access_control: {
    enabled: true,
    default_permission: "deny",
    rules: [
      { id: "operate", permission: "allow", flows: ["ingress", "egress"],
        messages: ["put", "delete", "declare_subscriber", "query", "reply", "declare_queryable",
                   "liveliness_token", "declare_liveliness_subscriber", "liveliness_query"],
        key_exprs: ["topgimbal/**"] },
    ],
    subjects: [ { id: "operators", usernames: ["operator", "server"] } ],
    policies: [ { rules: ["operate"], subjects: ["operators"] } ],
  },
}
"""


def _acl_files(tmp: Path) -> tuple[Path, Path]:
    (tmp / "users.txt").write_text("operator:op-pass\nserver:srv-pass\n")
    server = tmp / "server.json5"
    server.write_text(ACL.replace("DICT", str(tmp / "users.txt")))
    operator = tmp / "operator.json5"
    operator.write_text('{ transport: { auth: { usrpwd: { user: "operator", password: "op-pass" } } } }')
    return server, operator


# -- 33.1: exposure and restricted methods -------------------------------------------------------


def test_beyond_loopback_needs_access_control_or_insecure(tmp_path: Path) -> None:
    assert is_loopback("tcp/127.0.0.1:7447") and is_loopback("tcp/[::1]:7447") and is_loopback("tcp/localhost:1")
    assert not is_loopback("tcp/0.0.0.0:7447") and not is_loopback("tcp/192.168.1.5:7447")
    plain = make_config()
    assert check_exposure(["tcp/127.0.0.1:7447"], plain, False) == "loopback endpoints only"
    with pytest.raises(AccessConfigError, match="access_control"):
        check_exposure(["tcp/0.0.0.0:7447"], plain, False)
    assert check_exposure(["tcp/0.0.0.0:7447"], plain, True).startswith("INSECURE")
    server, _op = _acl_files(tmp_path)
    protected = make_config(config_file=str(server))
    assert "user/password" in check_exposure(["tcp/0.0.0.0:7447"], protected, False)
    with pytest.raises(AccessConfigError):
        check_allowed(["stop_attitude_stream"])
    with pytest.raises(AccessConfigError):
        check_allowed(["point"])
    assert check_allowed(["set_network"]) == {"set_network"}


async def test_cli_refuses_a_wide_endpoint_without_access_control(sims: Any) -> None:
    (sim,) = await sims(1)
    port = free_port()
    proc = await asyncio.create_subprocess_exec(
        sys.executable, "-m", "topgimbal.cli.main", "zenoh", "--listen", f"tcp/0.0.0.0:{port}", "--camera", f"a={sim.url},C12",
        stdout=asyncio.subprocess.PIPE, stderr=asyncio.subprocess.PIPE,
    )  # fmt: skip
    _out, err = await asyncio.wait_for(proc.communicate(), 60)
    assert proc.returncode == 2 and b"access_control" in err and b"--insecure" in err, err
    assert b"Traceback" not in err


async def test_network_raw_and_stream_calls_are_not_remote(sims: Any, zport: int) -> None:
    (sim,) = await sims(1)
    async with FleetServer([CameraSpec("a", sim.url, "C12")], listen=[f"tcp/127.0.0.1:{zport}"]):
        s = await asyncio.to_thread(raw_session, zport)
        try:
            samples: list[str] = []
            sub = s.declare_subscriber("topgimbal/a/attitude", lambda x: samples.append(x.payload.to_string()))
            await eventually(lambda: len(samples) >= 5, what="attitude")
            for method, args in [
                ("set_network", {"ip": "10.9.9.9"}),
                ("send_raw", {"frame": "#TPUG2wPTZ01"}),
                ("request", {"ident": "PTZ", "action": "stop"}),
                ("stop_attitude_stream", {}),
                ("attitude_stream", {"rate_hz": 1}),
            ]:
                got = await asyncio.to_thread(raw_call, s, f"topgimbal/a/call/{method}", json.dumps(args), 20.0)
                assert len(got) == 1 and got[0]["ok"] is False and got[0]["kind"] == "forbidden", (method, got)
            info = await asyncio.to_thread(raw_call, s, "topgimbal/a/info", None, 20.0)
            assert "set_network" not in info[0]["methods"] and "stop_attitude_stream" not in info[0]["methods"]
            # a read is harmless: callable
            got = await asyncio.to_thread(raw_call, s, "topgimbal/a/call/request", '{"ident": "GAC", "read": true}')
            assert got[0]["ok"] is True, got
            # the stream is still the server's: samples keep coming
            n = len(samples)
            await eventually(lambda: len(samples) >= n + 20, what="the attitude stream goes on")
            sub.undeclare()
        finally:
            s.close()
    # named by --allow-remote, it is callable
    async with FleetServer(
        [CameraSpec("a", sim.url, "C12")], listen=[f"tcp/127.0.0.1:{zport}"], allow_remote=frozenset({"request"})
    ):
        s = await asyncio.to_thread(raw_session, zport)
        try:
            got = await asyncio.to_thread(raw_call, s, "topgimbal/a/call/request", '{"ident": "PTZ", "action": "stop"}')
            assert got[0]["ok"] is True, got
        finally:
            s.close()


async def test_a_peer_without_credentials_is_refused_while_the_operator_works(
    sims: Any, zport: int, tmp_path: Path
) -> None:
    (sim,) = await sims(1)
    server_conf, operator_conf = _acl_files(tmp_path)
    ep = f"tcp/127.0.0.1:{zport}"
    async with FleetServer([CameraSpec("a", sim.url, "C12")], listen=[ep], config_file=str(server_conf)):
        with pytest.raises(Exception, match="Unable to connect"):
            await asyncio.to_thread(raw_session, zport)  # no user/password: the session never opens
        async with topgimbal.connect(f"zenoh/a?connect={ep}&config={operator_conf}") as cam:
            att = await cam.point(12, -8)
            assert abs(att.yaw_deg - 12) <= 0.5  # point()'s own tolerance, on the attitude it reported
            # the simulator's live axis went on to the target: point()'s tolerance is no bound on it
            # (it failed at 0.5013 once: the report rounds, the physics lags it)
            await near("the simulator's yaw", lambda: sim.gimbal.yaw_deg, 12, margin=SETTLED_DEG, bound_s=30)


async def test_insecure_is_repeated_in_the_log(
    monkeypatch: pytest.MonkeyPatch, caplog: pytest.LogCaptureFixture
) -> None:
    monkeypatch.setattr(server_mod, "INSECURE_LOG_EVERY_S", 0.05)
    server = FleetServer([CameraSpec("a", "udp://127.0.0.1:9", "C12")], insecure=True)
    server.protection = check_exposure(["tcp/0.0.0.0:7447"], make_config(), True)  # checked only: nothing listens
    with caplog.at_level(logging.WARNING, logger="topgimbal.fleet"):
        task = asyncio.ensure_future(server._repeat_insecure())
        await eventually(lambda: caplog.text.count("INSECURE: tcp/0.0.0.0:7447") >= 3, 10, "three warnings")
        task.cancel()


def test_zenoh_errors_lose_their_rust_source_path() -> None:
    exc = RuntimeError("Unable to connect to any of [tcp/127.0.0.1:1]!  at /root/.cargo/git/checkouts/zenoh/x.rs:447.")
    assert zenoh_error_text(exc) == "Unable to connect to any of [tcp/127.0.0.1:1]!"


# -- 33.2 / 33.4: bounded waits, a gone querier's places, a fair share ---------------------------


def _flood(port: int, n: int, payload: str, stop: threading.Event | None = None) -> Any:
    """A session naming itself (as RemoteClient does) that sends `n` slow calls at once, then
    waits for none of them; with `stop`, sends again until it is set."""
    s = raw_session(port)
    zid = str(s.zid())
    while True:
        handlers = [s.get("topgimbal/a/call/wait_attitude", payload=payload, timeout=60, attachment=zid)
                    for _ in range(n)]  # fmt: skip
        if stop is None:
            return s
        for h in handlers:
            list(h)
        if stop.is_set():
            s.close()
            return None


async def test_a_gone_querier_frees_its_places_and_waits_are_capped(
    sims: Any, zport: int, monkeypatch: pytest.MonkeyPatch
) -> None:
    (sim,) = await sims(1)
    monkeypatch.setattr(camera_mod, "MAX_ARG_TIMEOUT_S", 1.0)
    async with FleetServer([CameraSpec("a", sim.url, "C12")], listen=[f"tcp/127.0.0.1:{zport}"]) as server:
        cam = server.cameras["a"]
        s = await asyncio.to_thread(raw_session, zport)
        try:
            # a timeout_s of 1e9 is the server's cap
            got = await asyncio.to_thread(raw_call, s, "topgimbal/a/call/wait_attitude",
                                          '{"newer_than": 1e12, "timeout_s": 1e9}', 30.0)  # fmt: skip
            assert got[0]["ok"] is False and got[0]["kind"] == "timeout", got
        finally:
            s.close()
        monkeypatch.setattr(camera_mod, "MAX_ARG_TIMEOUT_S", 60.0)
        flooder = await asyncio.to_thread(_flood, zport, 8, '{"newer_than": 1e12, "timeout_s": 1e9}')
        # its share: 4 of 8 (the first session asked within the last 10 s too)
        await eventually(lambda: cam.inflight == 4, what="the flooder's calls in progress")
        await asyncio.to_thread(flooder.close)  # the peer leaves

        def calls() -> tuple[int, int, list[str], list[tuple[str, bool, bool, bool]]]:
            # what a timeout shows: calls in progress, gone, the open transports, each call's
            # (querier, named an open transport, done, cancelled)
            return (cam.inflight, cam.gone, sorted(cam._transports()),
                    [(q, d, t.done(), t in cam._cancelled) for t, (q, d) in cam._call_querier.items()])  # fmt: skip

        # Freed when the server's Zenoh drops the flooder's transport: at once when it reads the
        # close (1 ms here, quiet), at the latest when the transport's lease runs out (Zenoh's 10 s)
        # plus the 0.5 s poll; a fresh-clone run at load 8 saw more than 15 s (before `calls` said
        # what the server had then)
        await until("the gone querier's places freed", calls, lambda seen: seen[0] == 0, bound_s=30)
        # its 4 calls in progress; and any of its other 4 that Zenoh delivered after its transport
        # closed, taken as places freed and cancelled at once (a run under load saw 7)
        assert 4 <= cam.gone <= 8
        async with topgimbal.connect(f"zenoh/a?connect=tcp/127.0.0.1:{zport}") as op:
            assert await op.version()


class _Query:
    """What ServedCamera._on_query reads of a Zenoh query, and the replies it gets."""

    def __init__(self, key: str) -> None:
        self.key_expr = key
        self.payload = None
        self.attachment = None
        self.replies: list[tuple[str, str]] = []

    def __enter__(self) -> _Query:
        return self

    def __exit__(self, *exc: object) -> None:
        return None

    def reply(self, key: str, body: str) -> None:
        self.replies.append((key, body))


async def test_a_call_cancelled_before_it_ran_frees_its_place() -> None:
    """A call whose querier is seen gone in the same loop turn as it was accepted is cancelled
    before its coroutine first runs (so before any `finally` of it): its place is freed all the
    same, and it counts as gone once (it once stayed taken for good)."""
    session = type("Session", (), {"info": None})()  # no transports to list: nobody is present
    cam = camera_mod.ServedCamera(CameraSpec("a", "udp://127.0.0.1:9", "C12"), session)
    try:
        for _ in range(3):
            cam._on_query(_Query("topgimbal/a/call/wait_attitude"))
        assert cam.inflight == 3 and len(cam._call_querier) == 3
        cam._cancel_gone(set())  # before any of them ran
        assert cam.gone == 3
        await eventually(lambda: not cam._call_querier, what="the cancelled calls ended")
        assert cam.inflight == 0 and cam._by_querier == {}
        assert cam.gone == 3  # counted once each
        cam._on_query(q := _Query("topgimbal/a/call/version"))  # the places are free again
        assert cam.inflight == 1 and cam.refused == 0 and q.replies == []
    finally:
        for t in list(cam._calls):
            t.cancel()
        await asyncio.gather(*cam._calls, return_exceptions=True)
        await cam.client.close()


async def test_each_querier_gets_a_fair_share(sims: Any, zport: int) -> None:
    (sim,) = await sims(1)
    async with FleetServer([CameraSpec("a", sim.url, "C12")], listen=[f"tcp/127.0.0.1:{zport}"]) as server:
        stop = threading.Event()
        payload = '{"newer_than": 1e12, "timeout_s": 1.0}'
        floods = [asyncio.ensure_future(asyncio.to_thread(_flood, zport, 8, payload, stop)) for _ in range(4)]
        try:
            await eventually(lambda: server.cameras["a"].refused > 20, what="the flood at work")
            async with topgimbal.connect(f"zenoh/a?connect=tcp/127.0.0.1:{zport}") as op:
                # Its first call counts it among the queriers (refused or not: the flood holds every
                # place); the flooders' longer shares end within their 1 s calls.
                with contextlib.suppress(RemoteCallError):
                    await op.version()
                await asyncio.sleep(1.5)
                refused_before = server.cameras["a"].refused
                kinds = []
                for _ in range(20):
                    try:
                        await op.version()
                        kinds.append("ok")
                    except RemoteCallError as exc:
                        kinds.append(exc.kind)
                assert kinds == ["ok"] * 20, kinds
                # the flood went on all the while: it is still refused after the operator's calls
                # (a count of refusals in real time would measure the machine's speed, not the share)
                await until(
                    "a flooder refused after the operator's calls",
                    lambda: server.cameras["a"].refused,
                    lambda n: n > refused_before,
                    bound_s=20,
                )
        finally:
            stop.set()
            await asyncio.gather(*floods)


# -- 33.5: a lone surrogate ---------------------------------------------------------------------


def test_a_lone_surrogate_in_mavlink_in_is_a_counted_refusal(caplog: pytest.LogCaptureFixture) -> None:
    text = json.dumps({"header": {"system_id": 255, "component_id": 190},
                       "message": {"type": "STATUSTEXT", "severity": {"type": "MAV_SEVERITY_INFO"}, "text": "\udcff"}})  # fmt: skip
    with pytest.raises(json_shape.ShapeError, match="surrogate"):
        json_shape.loads(text.encode())
    delivered: list[Any] = []
    link = ZenohLink(None, lambda *a: delivered.append(a), lambda *a: None)
    link._pending = 2000
    with caplog.at_level(logging.WARNING, logger="topgimbal.mavlink"):
        for _ in range(2000):
            link._received(text.encode())
    assert link.bad_in == 2000 and not delivered
    assert "Traceback" not in caplog.text and len(caplog.records) == 1


# -- 33.6: one name, one server -------------------------------------------------------------------


async def test_a_second_server_for_a_served_name_refuses_and_a_client_never_acts_twice(sims: Any, zport: int) -> None:
    a, b = await sims(2)
    ep = f"tcp/127.0.0.1:{zport}"
    async with FleetServer([CameraSpec("left", a.url, "C12")], listen=[ep]):
        with pytest.raises(DuplicateCameraError, match="left"):
            await FleetServer([CameraSpec("left", b.url, "C12")], connect=[ep]).start()
        # a second server on a network of its own, both reached by one peer: it acts on neither
        ep2 = f"tcp/127.0.0.1:{free_port()}"
        async with FleetServer([CameraSpec("left", b.url, "C12")], listen=[ep2]):
            with pytest.raises(RemoteCallError, match="2 servers") as info:
                async with topgimbal.connect(f"zenoh/left?mode=peer&connect={ep}&connect={ep2}") as cam:
                    await cam.point(20, 0)
            assert info.value.kind == "served_twice"
            assert a.gimbal.yaw_deg == 0.0 and b.gimbal.yaw_deg == 0.0


async def test_the_cli_says_connected_and_logs_a_camera_link_coming_back(
    sims: Any, zport: int, caplog: pytest.LogCaptureFixture
) -> None:
    (sim,) = await sims(1)
    async with FleetServer([CameraSpec("a", sim.url, "C12")], listen=[f"tcp/127.0.0.1:{zport}"]):
        proc = await asyncio.create_subprocess_exec(
            sys.executable, "-m", "topgimbal.cli.main", "zenoh", "--connect", f"tcp/127.0.0.1:{zport}",
            "--camera", f"b={sim.url},C12", "--seconds", "1",
            stdout=asyncio.subprocess.PIPE, stderr=asyncio.subprocess.PIPE,
        )  # fmt: skip
        out, err = await asyncio.wait_for(proc.communicate(), 60)
        assert proc.returncode == 0, err
        assert f"serving 1 cameras connected to tcp/127.0.0.1:{zport} (peer)".encode() in out, out
        # the same name as the running server's: refused, exit 2
        proc = await asyncio.create_subprocess_exec(
            sys.executable, "-m", "topgimbal.cli.main", "zenoh", "--connect", f"tcp/127.0.0.1:{zport}",
            "--camera", f"a={sim.url},C12", "--seconds", "1",
            stdout=asyncio.subprocess.PIPE, stderr=asyncio.subprocess.PIPE,
        )  # fmt: skip
        out, err = await asyncio.wait_for(proc.communicate(), 60)
        assert proc.returncode == 2 and b"a: already served by another topgimbal zenoh" in err, err
        assert b"Traceback" not in err and b"serving" not in out
    served = camera_mod.ServedCamera(CameraSpec("x", "udp://127.0.0.1:9", "C12"), None)
    served._link = type("P", (), {"put": lambda self, v: None})()
    with caplog.at_level(logging.WARNING, logger="topgimbal.fleet"):
        served._on_link(False, "silent for 3 s")
        served._on_link(True, "")
    assert "x: camera link back (it was lost: silent for 3 s)" in caplog.text
