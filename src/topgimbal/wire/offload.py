"""Watching in a process of its own: the proxy process only forwards, a second process (at a lower
CPU priority) parses, captures, decodes, logs and prints.

Why: decoding, printing and logging a frame costs several times what forwarding it costs, and on
a machine shared with other work a process that uses more CPU waits longer for it when traffic
arrives. With the work elsewhere the forwarding process stays as light as `proxy --quiet`, and a
watcher that falls behind delays nothing on the link.

Parent side: `WatcherProcess(argv)` spawns `argv` (a program that calls `serve()`), sends it the
watcher's configuration, then `Chunk`s in batches over a pipe, never blocking the event loop: at
most `MAX_PENDING` bytes wait for the pipe (beyond, chunks are counted as dropped: still
forwarded, not watched). `stop()` sends the rest, says goodbye and returns the child's counters.
Child side: `serve(watcher, on_tick)` reads the chunks, runs them through the `Watcher`, flushes
every `FLUSH_S`, and at the end writes its counters back. Messages are length-prefixed pickles
between two processes of this program (never data from the network).
"""

from __future__ import annotations

import asyncio
import logging
import os
import pickle
import select
import struct
import subprocess
import sys
from collections.abc import Callable
from typing import Any

from ..clock import monotonic
from .watcher import Chunk, Watcher

log = logging.getLogger("topgimbal.proxy")

SHIP_S = 0.0005  # chunks wait this long to be sent in one batch
FLUSH_S = 0.2  # the child hands files and printed lines on this often
MAX_PENDING = 1024 * 1024  # bytes waiting for the pipe before chunks are dropped
_LEN = struct.Struct("<I")
NICE = 5  # the watcher yields the CPU to the forwarding process


def _message(obj: object) -> bytes:
    body = pickle.dumps(obj, protocol=pickle.HIGHEST_PROTOCOL)
    return _LEN.pack(len(body)) + body


class WatcherProcess:
    """The parent's end: a child process running a Watcher, fed without blocking."""

    def __init__(self, argv: list[str]) -> None:
        self.argv = argv
        self.proc: subprocess.Popen[bytes] | None = None
        self.dropped = 0
        self._fd = -1
        self._stats_r = -1
        self._batch: list[Chunk] = []
        self._pending = bytearray()
        self._ship_handle: asyncio.TimerHandle | None = None
        self._writing = False
        self._broken = False

    async def start(self, config: dict[str, Any]) -> None:
        stats_r, stats_w = os.pipe()
        self.proc = subprocess.Popen(
            [*self.argv, str(stats_w)], stdin=subprocess.PIPE, pass_fds=(stats_w,), close_fds=True
        )
        os.close(stats_w)
        self._stats_r = stats_r
        assert self.proc.stdin is not None
        self._fd = self.proc.stdin.fileno()
        self._pending += _message(config)
        os.set_blocking(self._fd, False)
        self._write()

    def submit(self, chunk: Chunk) -> None:
        """Send `chunk` soon (with whatever else comes within SHIP_S)."""
        if self._broken:
            return
        self._batch.append(chunk)
        if self._ship_handle is None:
            self._ship_handle = asyncio.get_running_loop().call_later(SHIP_S, self._ship)

    def _ship(self) -> None:
        self._ship_handle = None
        batch, self._batch = self._batch, []
        if not batch or self._broken:
            return
        data = _message(batch)
        if len(self._pending) + len(data) > MAX_PENDING:
            if not self.dropped:
                log.error(
                    "proxy: the watcher process is %d bytes behind; skipping chunks (still forwarded)", MAX_PENDING
                )
            self.dropped += len(batch)
            return
        self._pending += data
        self._write()

    def _write(self) -> None:
        loop = asyncio.get_running_loop()
        try:
            n = os.write(self._fd, self._pending) if self._pending else 0
        except BlockingIOError:
            n = 0
        except OSError as exc:  # the child is gone: forwarding goes on, watching stops
            log.error("proxy: the watcher process stopped (%s); frames are no longer decoded", exc)
            self._broken = True
            self._pending.clear()
            n = 0
        del self._pending[:n]
        if self._pending and not self._writing:
            loop.add_writer(self._fd, self._write)
            self._writing = True
        elif not self._pending and self._writing:
            loop.remove_writer(self._fd)
            self._writing = False

    async def stop(self, timeout_s: float = 30.0) -> dict[str, int]:
        """Send what waits and the end, wait for the child; its counters ({} if it failed)."""
        if self.proc is None:
            return {}
        if self._ship_handle is not None:
            self._ship_handle.cancel()
            self._ship()
        if self._writing:
            asyncio.get_running_loop().remove_writer(self._fd)
            self._writing = False
        stats: dict[str, int] = {}
        try:
            if not self._broken:
                os.set_blocking(self._fd, True)
                self._pending += _message(None)
                await asyncio.to_thread(self._write_all)
            assert self.proc.stdin is not None
            self.proc.stdin.close()
            await asyncio.to_thread(self.proc.wait, timeout_s)
            raw = await asyncio.to_thread(os.read, self._stats_r, 65536)
            stats = pickle.loads(raw) if raw else {}
        except (OSError, subprocess.TimeoutExpired, pickle.UnpicklingError, EOFError) as exc:
            log.error("proxy: the watcher process did not finish cleanly: %s", exc)
            self.proc.kill()
        finally:
            os.close(self._stats_r)
        return stats

    def _write_all(self) -> None:
        try:
            while self._pending:
                n = os.write(self._fd, self._pending)
                del self._pending[:n]
        except OSError:
            self._pending.clear()


def _read_exact(fd: int, n: int) -> bytes | None:
    out = bytearray()
    while len(out) < n:
        piece = os.read(fd, n - len(out))
        if not piece:
            return None
        out += piece
    return bytes(out)


def read_config(fd: int = 0) -> dict[str, Any]:
    """The child's first message: the watcher's configuration."""
    head = _read_exact(fd, _LEN.size)
    body = _read_exact(fd, _LEN.unpack(head)[0]) if head else None
    if body is None:
        raise EOFError("the proxy sent no configuration")
    config = pickle.loads(body)
    assert isinstance(config, dict)
    return config


def serve(watcher: Watcher, on_tick: Callable[[], None], fd: int = 0, stats_fd: int | None = None) -> None:
    """Run chunks from `fd` through `watcher` until the parent says goodbye (or goes away);
    `on_tick` and the watcher's files are flushed every FLUSH_S and at the end."""
    if hasattr(os, "nice"):
        os.nice(NICE)
    stats_fd = stats_fd if stats_fd is not None else int(sys.argv[-1])
    buf = bytearray()
    done = False
    next_flush = monotonic() + FLUSH_S
    try:
        while not done:
            ready, _, _ = select.select([fd], [], [], max(0.0, next_flush - monotonic()))
            if ready:
                piece = os.read(fd, 1 << 16)
                if not piece:
                    break
                buf += piece
                while len(buf) >= _LEN.size:
                    (n,) = _LEN.unpack_from(buf)
                    if len(buf) < _LEN.size + n:
                        break
                    batch = pickle.loads(bytes(buf[_LEN.size : _LEN.size + n]))
                    del buf[: _LEN.size + n]
                    if batch is None:
                        done = True
                        break
                    for chunk in batch:
                        watcher.run(chunk)
            if monotonic() >= next_flush:
                watcher.flush()
                on_tick()
                next_flush = monotonic() + FLUSH_S
    finally:
        watcher.close()
        on_tick()
        os.write(stats_fd, pickle.dumps(watcher.stats.as_dict()))
        os.close(stats_fd)
