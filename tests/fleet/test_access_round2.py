"""Issue 43: only the operator acts, round 2. Each test attacks the server as the independent test
did (eclipse-zenoh sessions of its own, none of our client code unless it is the operator's)."""

from __future__ import annotations

import asyncio
import os
import secrets
import sys
import threading
from pathlib import Path
from typing import Any

import pytest

import topgimbal
from topgimbal.client.remote_keys import RemoteCallError
from topgimbal.client.zenoh_session import final_endpoints, make_config
from topgimbal.fleet import CameraSpec, FleetServer
from topgimbal.fleet import camera as camera_mod
from topgimbal.fleet.access import AccessConfigError, check_exposure
from waiting import until

from .conftest import eventually, free_port, raw_session

pytestmark = pytest.mark.loopback


def listening_sockets(pid: int) -> list[str]:
    """`address:port` of every TCP socket in LISTEN that process `pid` holds (from /proc: what the
    kernel says, not what the program says it does)."""
    inodes = set()
    for fd in os.listdir(f"/proc/{pid}/fd"):
        try:
            target = os.readlink(f"/proc/{pid}/fd/{fd}")
        except OSError:  # closed meanwhile
            continue
        if target.startswith("socket:["):
            inodes.add(target[8:-1])
    out = []
    for table in ("tcp", "tcp6"):
        with open(f"/proc/{pid}/net/{table}") as f:
            for line in f.readlines()[1:]:
                cols = line.split()
                if cols[3] == "0A" and cols[9] in inodes:  # 0A: LISTEN
                    addr, port = cols[1].split(":")
                    out.append(f"{table}:{addr}:{int(port, 16)}")
    return out


# -- 43.1: Zenoh listens on what it was told, nothing else ---------------------------------------


def test_the_final_configuration_is_what_is_judged(tmp_path: Path) -> None:
    # no --listen: Zenoh's peer default (tcp/[::]:0, every interface) is replaced by none
    listen, connect = final_endpoints(make_config(connect=["tcp/127.0.0.1:7447"]), "peer")
    assert listen == [] and connect == ["tcp/127.0.0.1:7447"]
    conf_file = tmp_path / "wide.json5"
    conf_file.write_text('{ listen: { endpoints: ["tcp/0.0.0.0:7448"] } }')
    conf = make_config(connect=["tcp/127.0.0.1:7447"], config_file=str(conf_file))
    assert final_endpoints(conf, "peer")[0] == ["tcp/0.0.0.0:7448"]  # asked for in the file: kept
    with pytest.raises(AccessConfigError, match=r"tcp/0\.0\.0\.0:7448"):
        check_exposure(["tcp/127.0.0.1:7447"], conf, False)


async def _zenoh_cli(*args: str) -> asyncio.subprocess.Process:
    return await asyncio.create_subprocess_exec(
        sys.executable, "-m", "topgimbal.cli.main", "zenoh", *args,
        stdout=asyncio.subprocess.PIPE, stderr=asyncio.subprocess.PIPE,
    )  # fmt: skip


async def test_connect_only_listens_nowhere_and_a_wide_config_listener_is_refused(
    sims: Any, zport: int, tmp_path: Path
) -> None:
    (sim,) = await sims(1)
    listener = await asyncio.to_thread(raw_session, zport, "peer", [f"tcp/127.0.0.1:{zport}"])
    try:
        proc = await _zenoh_cli("--connect", f"tcp/127.0.0.1:{zport}", "--camera", f"a={sim.url},C12",
                                "--seconds", "60")  # fmt: skip
        try:
            assert proc.stdout is not None
            line = await asyncio.wait_for(proc.stdout.readline(), 60)
            assert b"serving 1 cameras" in line, line
            assert listening_sockets(proc.pid) == []  # the kernel's word: no listener at all
        finally:
            proc.terminate()
            await asyncio.wait_for(proc.communicate(), 60)
        wide = tmp_path / "wide.json5"
        wide.write_text(f'{{ listen: {{ endpoints: ["tcp/0.0.0.0:{free_port()}"] }} }}')
        proc = await _zenoh_cli("--connect", f"tcp/127.0.0.1:{zport}", "--config", str(wide),
                                "--camera", f"a={sim.url},C12", "--seconds", "5")  # fmt: skip
        _out, err = await asyncio.wait_for(proc.communicate(), 60)
        assert proc.returncode == 2 and b"tcp/0.0.0.0:" in err and b"access_control" in err, err
    finally:
        await asyncio.to_thread(listener.close)


# -- 43.2: the documented ACL: viewers and operators only subscribe and query --------------------

DOCS = Path(__file__).parents[2] / "docs" / "fleet.md"


def documented_acl(tmp: Path) -> Path:
    """docs/fleet.md's server.json5, as written there (only the dictionary's path made absolute)."""
    text = DOCS.read_text(encoding="utf-8")
    start = text.index("```json5\n// server.json5")
    body = text[text.index("\n", start) + 1 : text.index("```", start + 8)]
    (tmp / "users.txt").write_text("operator:op-pass\nserver:srv-pass\nviewer:v-pass\n")
    out = tmp / "server.json5"
    out.write_text(body.replace('dictionary_file: "users.txt"', f'dictionary_file: "{tmp / "users.txt"}"'))
    return out


def user_session(port: int, user: str, password: str) -> Any:
    """An eclipse-zenoh client session logged in as `user`."""
    import json

    import zenoh

    conf = zenoh.Config()
    for k, v in (("mode", "client"), ("connect/endpoints", [f"tcp/127.0.0.1:{port}"]),
                 ("scouting/multicast/enabled", False), ("scouting/gossip/enabled", False),
                 ("transport/auth/usrpwd/user", user), ("transport/auth/usrpwd/password", password)):  # fmt: skip
        conf.insert_json5(k, json.dumps(v))
    return zenoh.open(conf)


def all_replies(session: Any, key: str, payload: str = "{}") -> list[str]:
    import zenoh

    got = session.get(key, payload=payload, timeout=5, consolidation=zenoh.ConsolidationMode.NONE)
    return [r.ok.payload.to_string() for r in got if r.ok is not None]


async def test_the_documented_acl_lets_no_viewer_or_operator_publish_or_answer(
    sims: Any, zport: int, tmp_path: Path
) -> None:
    (sim,) = await sims(1)
    conf = documented_acl(tmp_path)
    async with FleetServer([CameraSpec("a", sim.url, "C12")], listen=[f"tcp/127.0.0.1:{zport}"],
                           config_file=str(conf)):  # fmt: skip
        op = await asyncio.to_thread(user_session, zport, "operator", "op-pass")
        viewer = await asyncio.to_thread(user_session, zport, "viewer", "v-pass")
        rogue = await asyncio.to_thread(user_session, zport, "operator", "op-pass")
        try:
            seen: list[str] = []
            subs = [op.declare_subscriber(f"topgimbal/a/{k}", lambda s: seen.append(s.payload.to_string()))
                    for k in ("attitude", "state", "link")]  # fmt: skip
            watched: list[str] = []
            vsub = viewer.declare_subscriber("topgimbal/a/attitude", lambda s: watched.append("x"))
            await eventually(lambda: len(seen) >= 10 and len(watched) >= 10, what="the server's samples")
            # the viewer forges samples, a camera's token and an answer; a second operator forges an answer
            for k in ("attitude", "state", "link"):
                for _ in range(20):
                    viewer.put(f"topgimbal/a/{k}", '{"forged": true}')
            token = viewer.liveliness().declare_token("topgimbal/phantom")
            rogue_tokens = [rogue.liveliness().declare_token("topgimbal/ghost")]
            forged = '{"ok": true, "result": "forged"}'
            answerers = [s.declare_queryable("topgimbal/a/call/version", lambda q: q.reply(q.key_expr, forged))
                         for s in (viewer, rogue)]  # fmt: skip
            n = len(seen)
            await eventually(lambda: len(seen) >= n + 50, what="real samples after the forged ones")
            assert not [x for x in seen if "forged" in x]
            tokens = await asyncio.to_thread(
                lambda: [str(r.ok.key_expr) for r in op.liveliness().get("topgimbal/*", timeout=3) if r.ok]
            )
            assert tokens == ["topgimbal/a"], tokens
            replies = await asyncio.to_thread(all_replies, op, "topgimbal/a/call/version")
            assert len(replies) == 1 and "forged" not in replies[0] and '"ok": true' in replies[0], replies
            # a viewer reads but does not call
            assert await asyncio.to_thread(all_replies, viewer, "topgimbal/a/call/point", '{"yaw_deg": 30}') == []
            assert sim.gimbal.yaw_deg == 0.0
            # the operator's own client works under these rules
            (tmp_path / "operator.json5").write_text('{ transport: { auth: { usrpwd: { user: "operator", '
                                                     'password: "op-pass" } } } }')  # fmt: skip
            async with topgimbal.connect(
                f"zenoh/a?connect=tcp/127.0.0.1:{zport}&config={tmp_path}/operator.json5"
            ) as cam:
                assert abs((await cam.point(12, -8)).yaw_deg - 12) <= 0.5
            for d in [*subs, vsub, token, *rogue_tokens, *answerers]:
                d.undeclare()
        finally:
            for s in (op, viewer, rogue):
                await asyncio.to_thread(s.close)


# -- 43.3: a share that cannot be faked; calls of a closed transport cancelled -----------------------

SLOW = '{"newer_than": 1e12, "timeout_s": 5.0}'  # a wait_attitude nobody's camera will satisfy


def _invent_flood(port: int, stop: threading.Event) -> None:
    """A logged-in peer sending slow calls 8 at a time, each under a new invented session id (and
    some under none), until `stop`."""
    s = raw_session(port)
    try:
        while not stop.is_set():
            hs = [s.get("topgimbal/a/call/wait_attitude", payload=SLOW, timeout=30,
                        attachment=(secrets.token_hex(16) if i % 4 else None)) for i in range(8)]  # fmt: skip
            for h in hs:
                list(h)
    finally:
        s.close()


async def test_invented_names_take_no_place_from_the_operator(sims: Any, zport: int) -> None:
    (sim,) = await sims(1)
    async with FleetServer([CameraSpec("a", sim.url, "C12")], listen=[f"tcp/127.0.0.1:{zport}"]) as server:
        cam = server.cameras["a"]
        stop = threading.Event()
        floods = [asyncio.ensure_future(asyncio.to_thread(_invent_flood, zport, stop)) for _ in range(2)]
        try:
            await eventually(lambda: cam.refused > 20, what="the flood at work")
            async with topgimbal.connect(f"zenoh/a?connect=tcp/127.0.0.1:{zport}") as op:
                kinds = []
                for _ in range(30):
                    try:
                        await op.version()
                        kinds.append("ok")
                    except RemoteCallError as exc:
                        kinds.append(exc.kind)
            refused = cam.refused
            # the flood went on all the while: it is still refused after the operator's calls (a
            # count of refusals in real time measures the machine's speed: 27 at load, not > 100)
            await until("a flooder refused after the operator's calls", lambda: cam.refused,
                        lambda n: n > refused, bound_s=30)  # fmt: skip
        finally:
            stop.set()
            await asyncio.gather(*floods)
    print(f"operator: {kinds.count('ok')} ok of {len(kinds)} under the flood ({refused} flood calls refused)")
    assert kinds.count("ok") >= 27, kinds  # issue 43's bar: 90 % of the baseline (all ok alone)


async def test_a_closed_transports_calls_are_cancelled_by_its_close_event(
    sims: Any, zport: int, monkeypatch: pytest.MonkeyPatch
) -> None:
    (sim,) = await sims(1)
    monkeypatch.setattr(camera_mod, "GONE_CHECK_S", 3600.0)  # the poll out of the way: the event alone
    async with FleetServer([CameraSpec("a", sim.url, "C12")], listen=[f"tcp/127.0.0.1:{zport}"]) as server:
        cam = server.cameras["a"]
        s = await asyncio.to_thread(raw_session, zport)
        zid = str(s.zid())
        handlers = [s.get("topgimbal/a/call/wait_attitude", payload=SLOW.replace("5.0", "60"), timeout=90,
                          attachment=zid) for _ in range(8)]  # fmt: skip
        await eventually(lambda: cam.inflight >= 7, what="its calls in progress")
        held = cam.inflight
        t0 = asyncio.get_running_loop().time()
        await asyncio.to_thread(s.close)
        await eventually(lambda: cam.inflight == 0, 30, "the closed transport's calls cancelled")
        print(f"cancelled {asyncio.get_running_loop().time() - t0:.3f} s after close()")
        assert cam.gone == held
        del handlers


# -- 43.4: console --zenoh reaches an access-controlled server ----------------------------------


async def test_the_console_reaches_a_server_with_access_control(sims: Any, zport: int, tmp_path: Path) -> None:
    import aiohttp

    from topgimbal.console import ConsoleServer

    (sim,) = await sims(1)
    conf = documented_acl(tmp_path)
    operator = tmp_path / "operator.json5"
    operator.write_text('{ transport: { auth: { usrpwd: { user: "operator", password: "op-pass" } } } }')
    ep = f"tcp/127.0.0.1:{zport}"
    async with FleetServer([CameraSpec("a", sim.url, "C12")], listen=[ep], config_file=str(conf)):
        console = ConsoleServer(zenoh=[ep], zenoh_config=str(operator), port=0)
        await console.start()
        try:
            async with aiohttp.ClientSession() as http:
                cams: dict[str, Any] = {}

                async def up() -> bool:
                    async with http.get(console.base_url + "api/cameras") as r:
                        cams.update({c["name"]: c for c in (await r.json())["cameras"]})
                    return "a" in cams and cams["a"]["link"] == "up" and cams["a"]["attitude"] is not None

                loop = asyncio.get_running_loop()
                end = loop.time() + 60
                while not await up():
                    assert loop.time() < end, cams
                    await asyncio.sleep(0.2)
        finally:
            await console.stop()
    # without --zenoh it has nothing to configure: refused, exit 2
    proc = await asyncio.create_subprocess_exec(
        sys.executable, "-m", "topgimbal.cli.main", "console", "--sim", "C12", "--zenoh-config", str(operator),
        "--port", "0", stdout=asyncio.subprocess.PIPE, stderr=asyncio.subprocess.PIPE,
    )  # fmt: skip
    _out, err = await asyncio.wait_for(proc.communicate(), 60)
    assert proc.returncode == 2 and b"--zenoh-config" in err and b"only with --zenoh" in err, err
    # a file Zenoh cannot parse: exit 2, its parser's drawing on one line
    (tmp_path / "bad.json5").write_text("{ nope")
    proc = await asyncio.create_subprocess_exec(
        sys.executable, "-m", "topgimbal.cli.main", "console", "--zenoh", ep, "--zenoh-config",
        str(tmp_path / "bad.json5"), "--port", "0", stdout=asyncio.subprocess.PIPE, stderr=asyncio.subprocess.PIPE,
    )  # fmt: skip
    _out, err = await asyncio.wait_for(proc.communicate(), 60)
    assert proc.returncode == 2 and err.count(b"\n") == 1 and b"bad.json5" in err, err


async def test_calls_naming_no_transport_end_when_no_transport_is_left(
    sims: Any, zport: int, monkeypatch: pytest.MonkeyPatch
) -> None:
    (sim,) = await sims(1)
    monkeypatch.setattr(camera_mod, "GONE_CHECK_S", 3600.0)  # the close event alone
    async with FleetServer([CameraSpec("a", sim.url, "C12")], listen=[f"tcp/127.0.0.1:{zport}"]) as server:
        cam = server.cameras["a"]
        s = await asyncio.to_thread(raw_session, zport)
        slow = SLOW.replace("5.0", "60")
        handlers = [s.get("topgimbal/a/call/wait_attitude", payload=slow, timeout=90) for _ in range(8)]  # anonymous
        await eventually(lambda: cam.inflight >= 1, what="its anonymous calls in progress")
        held = cam.inflight
        await asyncio.to_thread(s.close)  # the only session leaves: nobody can read those answers
        await eventually(lambda: cam.inflight == 0, 30, "the anonymous calls cancelled")
        assert cam.gone == held
        del handlers
