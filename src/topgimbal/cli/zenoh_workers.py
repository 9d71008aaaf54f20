"""`topgimbal zenoh` over several worker processes: past MAX_CAMERAS (or with `--workers K`) the
cameras are split into K shares, each served by a child `topgimbal zenoh` process of its own (one
Python event loop per share, so the shares run on every core).

Without a home-made relay: in peer mode (`--listen`) this process is a Zenoh *router* on the
given endpoints plus one loopback endpoint (with the whole `--config`: its ACL guards them), and
each worker a Zenoh client of it with the file's credentials only (`worker_config`); with
`--mode client --connect ROUTER` the workers connect to that router themselves, with the file as
it is, and this process only supervises. Subscribers see one key layout: one camera
per key prefix, whichever process serves it (docs/fleet.md, "Many cameras on one machine").

A worker that ends ends the whole server (its exit status, its message on stderr); a worker
whose parent has gone stops within PARENT_CHECK_S."""

from __future__ import annotations

import argparse
import asyncio
import contextlib
import json
import math
import os
import signal
import socket
import sys
import tempfile
from collections.abc import Sequence
from pathlib import Path
from typing import Any

from ..errors import FieldValueError
from ..timeouts import within

MAX_TOTAL_CAMERAS = 4096  # per `topgimbal zenoh` with its workers
MAX_WORKERS = 64
# Attitude samples a second one worker takes by default: 1,000 cameras at 50 Hz in one process used
# 85 % of a core on the 2-core reference machine (docs/fleet.md); more processes than that only
# add wake-ups, each with cold caches, and a Zenoh hop (4 processes: 21 us a sample, p99 23 ms).
SAMPLES_PER_WORKER = 50_000
WORKER_START_S = 300.0  # for a worker to print its serving line (1,024 cameras on a loaded host)
WORKER_STOP_S = 30.0  # after SIGINT, then SIGKILL
PARENT_CHECK_S = 1.0


def worker_count(cameras: int, asked: int, per_process: int, rate_hz: float = 0.0, cpus: int | None = None) -> int:
    """Worker processes for `cameras`: `asked` when given; 0: as few as hold them (at most
    `per_process` each) and take their samples (`rate_hz` each, SAMPLES_PER_WORKER a process, no
    more processes than `cpus` for that). 1 means this process serves them itself."""
    if cameras > MAX_TOTAL_CAMERAS:
        raise FieldValueError("camera", cameras, f"at most {MAX_TOTAL_CAMERAS} cameras per topgimbal zenoh")
    least = -(-cameras // per_process)
    if asked == 0:
        by_load = max(1, math.ceil(cameras * max(0.0, rate_hz) / SAMPLES_PER_WORKER))
        return max(least, min(by_load, cpus if cpus is not None else os.cpu_count() or 1, cameras))
    if asked < least:
        raise FieldValueError("--workers", asked, f"at least {least} for {cameras} cameras ({per_process} each)")
    return min(asked, cameras)


def shares(items: Sequence[Any], k: int) -> list[list[Any]]:
    """`items` in k contiguous shares whose sizes differ by at most one."""
    q, r = divmod(len(items), k)
    out, at = [], 0
    for i in range(k):
        n = q + (i < r)
        out.append(list(items[at : at + n]))
        at += n
    return out


def unique(specs: Sequence[Any]) -> list[Any]:
    seen: set[str] = set()
    for s in specs:
        if s.name in seen:
            raise FieldValueError("camera", s.name, "each camera name once")
        seen.add(s.name)
    return list(specs)


def refused_with_workers(args: argparse.Namespace) -> str | None:
    for flag, on in (("--mavlink-keys", args.mavlink_keys), ("--cot", args.cot), ("--status", args.status)):
        if on:
            return f"{flag} serves one process's cameras: not with worker processes (at most 256 cameras, --workers 1)"
    if args.config and _config_listens(args.config):
        return f"--config {args.config}: give the endpoints with --listen (workers must not listen on them too)"
    return None


def _config_listens(path: str) -> bool:
    import zenoh

    try:  # Zenoh's default endpoints are a per-mode table; a file that sets its own differs
        return bool(
            zenoh.Config.from_file(path).get_json("listen/endpoints") != zenoh.Config().get_json("listen/endpoints")
        )
    except Exception:  # unreadable: the server's own check says so
        return False


def worker_config(path: str, out: Path) -> str:
    """A worker behind this process's router: the `--config` file's transport section (its
    user/password or TLS, which the router's access control checks), without its access_control:
    a worker reaches only the router, on loopback, and the router presents no credentials a
    worker's ACL could name (user/password authenticates the side that connects only)."""
    import zenoh

    transport = json.loads(zenoh.Config.from_file(path).get_json("transport"))
    out.write_text(json.dumps({"transport": transport}))
    out.chmod(0o600)  # it may hold a password
    return str(out)


def worker_argv(args: argparse.Namespace, cameras_file: str, connect: Sequence[str], config: str | None) -> list[str]:
    argv = [sys.executable, "-m", "topgimbal.cli.main", "zenoh", "--cameras", cameras_file, "--mode", "client",
            "--workers", "1", "--rate-hz", repr(args.rate_hz), "--max-calls", str(args.max_calls),
            "--timeout", repr(args.timeout), "--batch-ms", repr(args.batch_ms),
            "--parent-pid", str(os.getpid())]  # fmt: skip
    for e in connect:
        argv += ["--connect", e]
    if config:
        argv += ["--config", config]
    for m in args.allow_remote:
        argv += ["--allow-remote", m]
    if args.insecure:
        argv.append("--insecure")
    if args.verbose:
        argv.append("-v")
    return argv


def _loopback_endpoint() -> str:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return f"tcp/127.0.0.1:{s.getsockname()[1]}"


def _open_router(args: argparse.Namespace, inner: str) -> Any:
    """The workers' router: the user's endpoints and config, plus `inner` for the workers."""
    import zenoh

    from ..client.zenoh_session import make_config, zenoh_error_text
    from ..errors import TransportError

    conf = make_config(listen=[*args.listen, inner], connect=args.connect, mode="peer", config_file=args.config)
    conf.insert_json5("mode", json.dumps("router"))
    try:
        return zenoh.open(conf)
    except Exception as exc:
        raise TransportError(f"cannot open the workers' Zenoh router: {zenoh_error_text(exc)}") from None


async def _first_line(proc: asyncio.subprocess.Process) -> str:
    assert proc.stdout is not None
    return (await proc.stdout.readline()).decode(errors="replace").strip()


async def _stop(procs: Sequence[asyncio.subprocess.Process]) -> None:
    for p in procs:
        if p.returncode is None:
            with contextlib.suppress(ProcessLookupError):
                p.send_signal(signal.SIGINT)
    for p in procs:
        try:
            await within(p.wait(), WORKER_STOP_S)
        except asyncio.TimeoutError:
            with contextlib.suppress(ProcessLookupError):
                p.kill()
            await p.wait()


async def serve_workers(specs: Sequence[Any], k: int, args: argparse.Namespace, where: str) -> int:
    """Starts k workers, prints one serving line, runs until a signal or a worker's end."""
    from .runtime import stop_on_signals, wait_stopped

    stop = stop_on_signals()
    router = None
    procs: list[asyncio.subprocess.Process] = []
    with tempfile.TemporaryDirectory(prefix="topgimbal-zenoh-") as tmp:
        try:
            if args.mode == "client":  # straight to the user's router, with the user's config
                connect, config = list(args.connect), args.config
            else:
                inner = _loopback_endpoint()
                router = await asyncio.to_thread(_open_router, args, inner)
                connect = [inner]
                config = worker_config(args.config, Path(tmp) / "worker.json5") if args.config else None
            for i, share in enumerate(shares(specs, k)):
                path = Path(tmp) / f"cameras-{i}.json"
                path.write_text(json.dumps([{"name": s.name, "url": s.url, "model": s.model} for s in share]))
                path.chmod(0o600)
                procs.append(await asyncio.create_subprocess_exec(*worker_argv(args, str(path), connect, config),
                                                                  stdout=asyncio.subprocess.PIPE))  # fmt: skip
            try:
                lines = await within(asyncio.gather(*(_first_line(p) for p in procs)), WORKER_START_S)
            except asyncio.TimeoutError:  # TimeoutError itself from 3.11
                print(f"topgimbal zenoh: error: the workers did not all start within {WORKER_START_S:g} s",
                      file=sys.stderr)  # fmt: skip
                return 1
            failed = [i for i, line in enumerate(lines) if not line.startswith("zenoh: serving")]
            if failed:
                await _stop(procs)
                return next((p.returncode for p in procs if p.returncode), 1)
            print(f"zenoh: serving {len(specs)} cameras {where} ({args.mode}) in {k} worker processes: "
                  f"{specs[0].name} ({specs[0].model}) .. {specs[-1].name} ({specs[-1].model})", flush=True)  # fmt: skip
            ended = [asyncio.ensure_future(p.wait()) for p in procs]
            waiter = asyncio.ensure_future(wait_stopped(stop, args.seconds))
            done, _ = await asyncio.wait([waiter, *ended], return_when=asyncio.FIRST_COMPLETED)
            waiter.cancel()
            gone = [p for p in procs if p.returncode is not None]
            if gone and waiter not in done:
                print(f"topgimbal zenoh: error: worker process {gone[0].pid} ended (exit {gone[0].returncode}); "
                      "stopping the others", file=sys.stderr)  # fmt: skip
                return 1
            return 0
        finally:
            await _stop(procs)
            if router is not None:
                with contextlib.suppress(Exception):
                    await asyncio.to_thread(router.close)


async def watch_parent(parent_pid: int, stop: asyncio.Event) -> None:
    """A worker's own end when its parent has gone (a SIGKILL'd parent sends no SIGINT)."""
    while os.getppid() == parent_pid:
        await asyncio.sleep(PARENT_CHECK_S)
    stop.set()
