"""Cameras, a Zenoh router and an operator on three "machines" (network namespaces joined by veth
pairs, tests/fleet/netns.py), with Zenoh access control on: the cameras' `topgimbal zenoh` (two
worker processes, a camera each) is a client of the router (Zenoh's own, the Python package's
router mode; no relay of ours), the operator reaches the cameras only through it, with
credentials, and a session without them is refused. The topology of docs/fleet.md, "Several
machines"."""

from __future__ import annotations

import asyncio
import contextlib
import errno
import json
import sys
from collections.abc import AsyncIterator
from pathlib import Path

import pytest

from topgimbal.timeouts import within

from .netns import CAMS_IP, OP_IP, ROUTER_CAMS_IP, ROUTER_OP_IP, three_machines

pytestmark = pytest.mark.external  # drives iproute2's `ip` (root: it makes network namespaces)

PORT = 7447  # inside the router's namespace only
ROUTER_ZID = "a11ed7"  # the router's Zenoh id: the server's ACL names it (it presents no user/password)
# The router admits the operator and the server by their user/password; the server (a client of the
# router) admits the router by its Zenoh id: usrpwd authenticates the side that connects only.
ROUTER_SUBJECTS = '{ id: "operators", usernames: ["operator", "server"] }'
SERVER_SUBJECTS = f'{{ id: "operators", zids: ["{ROUTER_ZID}"] }}'

START_S = 120.0

ACL = """
    access_control: {
      enabled: true,
      default_permission: "deny",
      rules: [
        { id: "operate", permission: "allow", flows: ["ingress", "egress"],
          messages: ["put", "delete", "declare_subscriber", "query", "reply", "declare_queryable",
                     "liveliness_token", "declare_liveliness_subscriber", "liveliness_query"],
          key_exprs: ["topgimbal/**"] },
      ],
      subjects: [ SUBJECTS ],
      policies: [ { rules: ["operate"], subjects: ["operators"] } ],
    },"""

ROUTER_PY = """
import sys, zenoh
with zenoh.open(zenoh.Config.from_file(sys.argv[1])):
    print("router ready", flush=True)
    sys.stdin.read()  # until the test closes our stdin (or ends us)
"""

OPERATOR_PY = """
import asyncio, json, socket, sys, time, zenoh
import topgimbal
ep, conf_file, cams_ip, names = sys.argv[1], sys.argv[2], sys.argv[3], sys.argv[4:]
out = {}
with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as s:  # the cameras' machine, directly
    try:
        s.connect((cams_ip, 9))
        out["direct"] = "reachable"
    except OSError as exc:
        out["direct"] = exc.errno
def config(path):
    c = zenoh.Config.from_file(path) if path else zenoh.Config()
    for k, v in (("mode", "client"), ("connect/endpoints", [ep]), ("scouting/multicast/enabled", False),
                 ("scouting/gossip/enabled", False)):
        c.insert_json5(k, json.dumps(v))
    return c
try:
    zenoh.open(config(None)).close()
    out["anonymous"] = "opened"
except Exception:
    out["anonymous"] = "refused"
seen = {}
with zenoh.open(config(conf_file)) as z:
    z.declare_subscriber("topgimbal/*/attitude", lambda s: seen.__setitem__(str(s.key_expr), seen.get(str(s.key_expr), 0) + 1))
    end = time.monotonic() + 60
    while time.monotonic() < end and not all(seen.get(f"topgimbal/{n}/attitude", 0) >= 20 for n in names):
        time.sleep(0.1)
out["attitude"] = seen
async def calls():
    for n in names:
        async with topgimbal.connect(f"zenoh/{n}?connect={ep}&config={conf_file}") as cam:
            out[n] = await cam.version()
asyncio.run(calls())
print(json.dumps(out), flush=True)
"""


def _files(tmp: Path) -> dict[str, Path]:
    users = tmp / "users.txt"
    users.write_text("operator:op-pass\nserver:srv-pass\nrouter:rt-pass\n")
    users.chmod(0o600)
    auth = '{{ user: "{}", password: "{}", dictionary_file: "' + str(users) + '" }}'
    files = {
        "router.json5": f"""{{
    id: "{ROUTER_ZID}",
    mode: "router",
    listen: {{ endpoints: ["tcp/{ROUTER_CAMS_IP}:{PORT}", "tcp/{ROUTER_OP_IP}:{PORT}"] }},
    scouting: {{ multicast: {{ enabled: false }}, gossip: {{ enabled: false }} }},
    transport: {{ auth: {{ usrpwd: {auth.format("router", "rt-pass")} }} }},{ACL.replace("SUBJECTS", ROUTER_SUBJECTS)}
}}""",
        "server.json5": f"""{{
    transport: {{ auth: {{ usrpwd: {auth.format("server", "srv-pass")} }} }},{ACL.replace("SUBJECTS", SERVER_SUBJECTS)}
}}""",
        "operator.json5": '{ transport: { auth: { usrpwd: { user: "operator", password: "op-pass" } } } }',
        "router_side.py": ROUTER_PY,
        "op_side.py": OPERATOR_PY,
    }
    out = {}
    for name, text in files.items():
        out[name] = tmp / name
        out[name].write_text(text)
    return out


@contextlib.asynccontextmanager
async def _process(argv: list[str], ready: bytes | None) -> AsyncIterator[asyncio.subprocess.Process]:
    proc = await asyncio.create_subprocess_exec(
        *argv, stdin=asyncio.subprocess.PIPE, stdout=asyncio.subprocess.PIPE, stderr=asyncio.subprocess.PIPE
    )
    try:
        if ready is not None:
            assert proc.stdout is not None
            line = await within(proc.stdout.readline(), START_S)
            if ready not in line:
                err = await within(proc.stderr.read(), 10) if proc.stderr else b""
                raise AssertionError(f"{argv[4:7]}: {line!r} {err.decode(errors='replace')[-2000:]}")
        yield proc
    finally:
        if proc.returncode is None:
            proc.send_signal(2)  # SIGINT: a clean stop
            try:
                await within(proc.wait(), 30)
            except TimeoutError:
                proc.kill()
                await proc.wait()


async def _urls(proc: asyncio.subprocess.Process, n: int) -> list[str]:
    assert proc.stdout is not None
    return [(await within(proc.stdout.readline(), START_S)).decode().strip() for _ in range(n)]


async def test_operator_reaches_cameras_only_through_the_router_with_access_control(tmp_path: Path) -> None:
    f = _files(tmp_path)
    py, tg = sys.executable, [sys.executable, "-m", "topgimbal.cli.main"]
    names = ["ridge", "gate"]
    with three_machines() as m:
        async with (
            _process(m.exec(m.router, py, str(f["router_side.py"]), str(f["router.json5"])), b"router ready"),
            _process(m.exec(m.cams, *tg, "sim", "--model", "C12", "--fleet", "2", "--udp", "127.0.0.1:0"), None) as sims,
        ):  # fmt: skip
            urls = await _urls(sims, 2)
            cams = tmp_path / "cameras.txt"
            cams.write_text("".join(f"{n}={u},C12\n" for n, u in zip(names, urls, strict=True)))
            server = m.exec(m.cams, *tg, "zenoh", "--mode", "client", "--connect", f"tcp/{ROUTER_CAMS_IP}:{PORT}",
                            "--config", str(f["server.json5"]), "--cameras", str(cams), "--workers", "2")  # fmt: skip
            async with _process(server, b"in 2 worker processes"):  # a camera each, both clients of the router
                op = await asyncio.create_subprocess_exec(
                    *m.exec(m.operator, py, str(f["op_side.py"]), f"tcp/{ROUTER_OP_IP}:{PORT}",
                            str(f["operator.json5"]), CAMS_IP, *names),
                    stdout=asyncio.subprocess.PIPE, stderr=asyncio.subprocess.PIPE,
                )  # fmt: skip
                out, err = await within(op.communicate(), 180)
    assert op.returncode == 0, err.decode(errors="replace")[-3000:]
    got = json.loads(out)
    assert got["direct"] == errno.ENETUNREACH, got  # no path from the operator to the cameras but the router
    assert got["anonymous"] == "refused", got  # no credentials, no session
    for n in names:
        assert got["attitude"].get(f"topgimbal/{n}/attitude", 0) >= 20, got["attitude"]
        assert isinstance(got[n], str) and got[n], got  # the camera's version, a call through the router


def test_the_machines_are_made_and_removed(tmp_path: Path) -> None:
    import subprocess

    with three_machines() as m:
        listed = subprocess.run(["ip", "netns", "list"], capture_output=True, text=True, timeout=30).stdout
        assert all(ns in listed for ns in (m.cams, m.router, m.operator))
        probe = "import socket, sys; s = socket.socket(socket.AF_INET, socket.SOCK_DGRAM); s.connect((sys.argv[1], 9))"
        for addr, ok in ((ROUTER_OP_IP, True), (CAMS_IP, False)):  # on-link: a route; beyond the router: none
            run = subprocess.run(m.exec(m.operator, sys.executable, "-c", probe, addr), capture_output=True,
                                 timeout=60)  # fmt: skip
            assert (run.returncode == 0) is ok, (addr, run.stderr[-300:])
    listed = subprocess.run(["ip", "netns", "list"], capture_output=True, text=True, timeout=30).stdout
    assert not any(ns in listed for ns in (m.cams, m.router, m.operator)), listed
    assert OP_IP not in listed
