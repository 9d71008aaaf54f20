"""Issue 43: only the operator acts, round 2. Each test attacks the server as the independent test
did (eclipse-zenoh sessions of its own, none of our client code unless it is the operator's)."""

from __future__ import annotations

import asyncio
import os
import sys
from pathlib import Path
from typing import Any

import pytest

from topgimbal.client.zenoh_session import final_endpoints, make_config
from topgimbal.fleet.access import AccessConfigError, check_exposure

from .conftest import free_port, raw_session

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
