"""The blocking facade's life cycle under concurrency: calls from many threads, close() racing
calls, calls after close, an unclosed Gimbal dropped, a blocking call given up (timeout, Ctrl-C).
The bar: every call ends (a result or a clear TopGimbalError), never another call's reply, and
no thread, socket or file descriptor outlives its client. Bounded counts, no timing assertions."""

from __future__ import annotations

import asyncio
import gc
import json
import os
import random
import subprocess
import sys
import threading
from collections.abc import Iterator
from pathlib import Path

import pytest

import topgimbal
from topgimbal.errors import RequestTimeoutError, TopGimbalError
from topgimbal.sim import BackgroundSimulator

from .conftest import FakeDevice

pytestmark = [pytest.mark.loopback, pytest.mark.integration]

JOIN_S = 30.0  # a thread still alive after this is hung (the old code waited forever)


@pytest.fixture(scope="module")
def sip_url() -> Iterator[str]:
    with BackgroundSimulator("SIP", seed=5, listen={"udp": [("127.0.0.1", 0)]}) as bg:
        yield bg.url


def _fds() -> int:
    return len(os.listdir("/proc/self/fd"))


def _client_threads() -> list[threading.Thread]:
    return [t for t in threading.enumerate() if t.name == "topgimbal-loop"]


def test_many_threads_each_get_their_own_answer(sip_url: str) -> None:
    """16 threads x 200 mixed reads and writes on one Gimbal: each reply is its own request's."""
    wrong: list[tuple[str, str]] = []
    failures: list[BaseException] = []
    with topgimbal.Gimbal(sip_url, model="SIP", timeout_s=1.0, retries=3) as cam:

        def work(seed: int) -> None:
            rnd = random.Random(seed)
            for _ in range(200):
                choice = rnd.randrange(4)
                if choice == 0:  # the pitch rate names the thread: an echo of another thread's write differs
                    frame = cam.aio.build("GSM", yaw_rate_deg_s=rnd.randint(-50, 50), pitch_rate_deg_s=seed)
                elif choice == 1:
                    frame = cam.aio.build("BIT", bitrate_kbps=rnd.choice([1000, 2000, 4000]))
                else:
                    frame = cam.aio.build("GAC" if choice == 2 else "REC", read=True)
                try:
                    reply = cam._run(cam.aio.send_request(frame))
                except TopGimbalError as exc:  # a clear error is allowed (a busy loopback); a wrong answer is not
                    failures.append(exc)
                    continue
                except BaseException as exc:
                    failures.append(exc)
                    raise
                if reply.frame.ident != frame.ident or (
                    frame.rw == "w" and reply.frame.data.upper() != frame.data.upper()
                ):
                    wrong.append((frame.text(), reply.frame.text()))

        threads = [threading.Thread(target=work, args=(i,)) for i in range(16)]
        for t in threads:
            t.start()
        for t in threads:
            t.join(JOIN_S * 4)
        assert not any(t.is_alive() for t in threads)
    assert wrong == []
    assert all(isinstance(e, TopGimbalError) for e in failures), failures[:3]
    assert len(failures) < 16 * 200 // 10  # a few timeouts under load, not a broken client


def test_calls_after_close_raise_a_clear_error(sip_url: str) -> None:
    cam = topgimbal.Gimbal(sip_url, model="SIP", timeout_s=0.5)
    cam.close()
    cam.close()  # twice: nothing happens
    for call in (cam.recording, cam.cmd.recording.read, lambda: cam.subscribe(print), lambda: next(cam.attitude(10))):
        with pytest.raises(TopGimbalError, match="closed"):
            call()


def _call_until_closed(cam: topgimbal.Gimbal, stop: threading.Event, errors: list[BaseException]) -> None:
    while not stop.is_set():
        try:
            cam.recording()
        except TopGimbalError as exc:
            if "closed" in str(exc):
                return
        except BaseException as exc:
            errors.append(exc)
            return


def test_close_racing_calls_from_other_threads_never_hangs(sip_url: str) -> None:
    """Calls keep coming from 8 threads while the main thread closes: each ends with a result or
    a TopGimbalError saying the client is closed (the old code left a call that came in while the
    loop stopped waiting forever, in most rounds)."""
    for round_ in range(10):
        cam = topgimbal.Gimbal(sip_url, model="SIP", timeout_s=1.0, retries=3)
        stop = threading.Event()
        errors: list[BaseException] = []
        threads = [threading.Thread(target=_call_until_closed, args=(cam, stop, errors), daemon=True) for _ in range(8)]
        for t in threads:
            t.start()
        for _ in range(random.Random(round_).randrange(1, 40)):
            cam.recording()  # let the others get going; a varied moment of closing
        cam.close()
        stop.set()
        for t in threads:
            t.join(JOIN_S)
        assert [t for t in threads if t.is_alive()] == [], f"round {round_}: a call never returned"
        assert errors == []


def test_context_manager_left_with_an_exception_closes(sip_url: str) -> None:
    before = len(_client_threads())
    with pytest.raises(ValueError, match="boom"), topgimbal.Gimbal(sip_url, model="SIP", timeout_s=0.5) as cam:
        raise ValueError("boom")
    assert len(_client_threads()) == before
    with pytest.raises(TopGimbalError, match="closed"):
        cam.recording()


def test_an_unclosed_gimbal_dropped_leaves_no_thread_or_descriptor(sip_url: str) -> None:
    gc.collect()
    threads, fds = len(_client_threads()), _fds()
    for _ in range(5):
        cam = topgimbal.Gimbal(sip_url, model="SIP", timeout_s=0.5)
        assert cam.recording() in (True, False)
        del cam
        gc.collect()  # the facade holds a reference cycle (cam.cmd): the collector ends it
    # The old code kept every dropped client's thread, socket and loop running: +5 threads, +20 fds.
    assert len(_client_threads()) == threads
    assert _fds() == fds


def test_two_hundred_clients_opened_and_closed_leak_nothing(sip_url: str) -> None:
    gc.collect()
    threads, fds = threading.active_count(), _fds()
    for i in range(200):
        with topgimbal.Gimbal(sip_url, model="SIP", timeout_s=0.5, check_model=False, host_feeds=False) as cam:
            if i % 50 == 0:
                cam.recording()
    gc.collect()
    assert threading.active_count() == threads
    assert _fds() == fds


def test_a_blocking_call_given_up_is_cancelled_on_the_loop() -> None:
    """A blocking call that times out (a SyncAttitudeStream's timeout_s) must not leave its
    coroutine running for nobody: the old code left one task per timeout waiting on the loop."""
    from topgimbal.client.sync import ThreadLoop

    loop = ThreadLoop()
    try:
        for _ in range(5):
            with pytest.raises(TimeoutError):
                loop.run(asyncio.sleep(3600), timeout=0.01)

        async def others() -> int:
            await asyncio.sleep(0)  # the cancellations were queued before this call
            return len(asyncio.all_tasks()) - 1

        assert loop.run(others()) == 0
    finally:
        loop.stop()
    assert not loop.thread.is_alive()


def test_attitude_stream_timeout_is_a_request_timeout(sip_url: str) -> None:
    """A sync stream's timeout is a TopGimbalError (RequestTimeoutError, still a TimeoutError)."""
    with topgimbal.Gimbal(sip_url, model="SIP", timeout_s=0.5) as cam:
        stream = cam.attitude(1, timeout_s=0.001)
        got_timeout = False
        for _ in range(50):  # at 1 Hz, a wait of 1 ms almost always times out; bounded anyway
            try:
                next(stream)
            except RequestTimeoutError:
                got_timeout = True
                break
        stream.close()
        assert got_timeout


INTERRUPTED = r"""
import json, signal, socket, sys, threading
import topgimbal

silent = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)  # a device that hears and never answers
silent.bind(("127.0.0.1", 0))
url = "udp://127.0.0.1:%d" % silent.getsockname()[1]
cam = topgimbal.Gimbal(url, model="SIP", timeout_s=60, retries=0, check_model=False, host_feeds=False)

def interrupt(signum, frame):
    raise KeyboardInterrupt
signal.signal(signal.SIGALRM, interrupt)
signal.setitimer(signal.ITIMER_REAL, 0.3)
out = {}
try:
    cam.cmd.recording.read()
    out["interrupted"] = False
except KeyboardInterrupt:
    out["interrupted"] = True

async def live():
    import asyncio
    await asyncio.sleep(0)
    return len(cam.aio._engine.live)
out["live_after"] = cam._run(live())
cam.close()
out["threads_after_close"] = sum(t.name == "topgimbal-loop" for t in threading.enumerate())
print(json.dumps(out))
"""


def test_ctrl_c_in_a_blocking_call_cancels_its_request() -> None:
    """Ctrl-C (a signal) in a blocking call: the request is withdrawn from the engine (the old
    code left it in flight, holding its key for a minute), and the client still closes cleanly."""
    env = {**os.environ, "PYTHONPATH": os.pathsep.join(p for p in sys.path if p)}
    done = subprocess.run(
        [sys.executable, "-c", INTERRUPTED], capture_output=True, text=True, timeout=120, env=env, check=False
    )
    assert done.returncode == 0, done.stderr[-2000:]
    out = json.loads(done.stdout.strip().splitlines()[-1])
    assert out == {"interrupted": True, "live_after": 0, "threads_after_close": 0}


async def test_open_twice_is_refused_and_leaks_nothing(fake: FakeDevice) -> None:
    """A second open() used to open a second transport and drop the first one unclosed (its
    socket lived on after close(): +2 descriptors per extra open)."""
    url = await fake.start_udp()
    fds = _fds()
    cam = await topgimbal.connect(url, model="C12", timeout_s=0.3, check_model=False, host_feeds=False)
    with pytest.raises(TopGimbalError, match="open already"):
        await cam.open()
    assert (await cam.request("VER", read=True)).fields == {"version": "1.5.2"}
    await cam.close()
    with pytest.raises(TopGimbalError, match="closed"):
        await cam.open()
    await asyncio.sleep(0)  # the transports' own close callbacks
    assert _fds() == fds


async def test_a_failed_open_holds_nothing_and_may_be_retried(tmp_path: Path) -> None:
    """The transport does not open: the traffic log opened before it is closed at once (not at
    the garbage collector's leisure) and open() may simply be called again."""
    import socket

    sock = socket.socket()  # bound, not listening yet: connections are refused
    sock.bind(("127.0.0.1", 0))
    port = sock.getsockname()[1]
    try:
        fds = _fds()
        cam = topgimbal.AsyncClient(
            f"tcp://127.0.0.1:{port}", "C20", log_path=str(tmp_path / "t.jsonl"), check_model=False, host_feeds=False
        )
        with pytest.raises(TopGimbalError, match="cannot connect"):
            await cam.open()
        assert _fds() == fds  # the old code kept the log file open
        sock.listen()
        await cam.open()  # the old code said nothing here and opened a second engine's worth
        assert cam.connected_transport
        await cam.close()
    finally:
        sock.close()


def test_an_unclosed_gimbal_collected_on_its_own_loop_thread_ends_it(sip_url: str) -> None:
    """The collector may run the finalizer on the client's loop thread itself (which cannot wait
    for itself): the close is scheduled there and the thread still ends."""
    cam = topgimbal.Gimbal(sip_url, model="SIP", timeout_s=0.5)
    thread = cam._thread
    del cam
    thread.loop.call_soon_threadsafe(gc.collect)
    thread.thread.join(JOIN_S)
    assert not thread.thread.is_alive()
    assert thread.stopped
