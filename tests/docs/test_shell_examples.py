"""Every shell example in README.md and docs/*.md, run.

Each ```sh / ```bash / ```shell / ```console block is split into commands (comments, `$ ` prompts,
line continuations and `a|b|c` alternatives handled). Every `topgimbal ...` command runs through
the venv's entry point against simulators on loopback ephemeral ports: the documented camera
addresses, ports, placeholders (CAMERA, HOST, PORT) and serial devices are replaced by the test's
simulator of the model the command names (a pty bridged to the simulator's serial line for a
device path). Commands that listen or run until Ctrl-C (sim, proxy, console, mavlink) are started,
checked to come up (their first lines, an HTTP page, a MAVLink heartbeat, a frame through a
proxy) and stopped at the end of their block; commands that read a file a running one writes stop
it first. Output a comment promises (PROMISES, and any frame in a comment) must be printed.

A command that is not run is in NOT_RUN with its reason; `test_every_command_is_run_or_listed`
fails for a new example that is neither. Nothing is sent to a non-loopback address: every command
is checked after substitution (`_assert_loopback_only`).
"""

from __future__ import annotations

import contextlib
import ctypes
import os
import pty
import re
import select
import shlex
import shutil
import signal
import socket
import subprocess
import sys
import threading
import time
import tty
import urllib.request
from collections.abc import Iterator
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import pytest

from topgimbal.protocol import encode
from topgimbal.sim import BackgroundSimulator
from topgimbal.wire.synth import CaptureWriter

pytestmark = pytest.mark.external

ROOT = Path(__file__).resolve().parents[2]
DOCS = [ROOT / "README.md", *sorted((ROOT / "docs").glob("*.md"))]
SHELL_LANGS = ("sh", "bash", "shell", "console")
EXE = Path(sys.executable).with_name("topgimbal")
RUN_TIMEOUT_S = 60.0  # per command: generous for a loaded machine; a hang fails rather than blocks
LOOPBACK = {"127.0.0.1", "localhost", "::1"}

# Commands not run here, by their text as written (continuations joined, comment removed).
NOT_RUN: dict[str, str] = {
    "make demo": "runs until Ctrl-C on port 8080; tests/console/test_demo.py runs it",
    "make test": "the whole suite: it is what runs this test",
    "make check": "lint, types and the virtual tier: this test is in the loopback tier make test runs",
    "pip install -e .": "installs into the environment running the tests (make does it)",
    "pip install -e '.[serial]'": "installs into the environment running the tests (make does it)",
    "pip install -e '.[all]'": "installs into the environment running the tests (make does it)",
    "make bench": "benchmarks: minutes of CPU, figures only",
    "make flake RUNS=3 HOG=2": "the loopback and external tiers three times beside busy loops: most of an hour",
    "make docs": "rewrites docs/protocol.md in the work tree (tests/protocol checks it is current)",
    "python -m topgimbal.tools.cgen": "rewrites c/generated/ in the work tree; the --check beside it runs",
    "python -m topgimbal.tools.regen": "rewrites generated files in the work tree; the --check beside it runs",
    "make -C c test": "the C library's own suite (sanitizers, fuzzers): minutes; `make test` runs it",
    "make -C c deps": "apt-get install as root",
    "ffplay -rtsp_transport tcp rtsp://127.0.0.1:8554/stream=0": "a video window (GUI); tests/video play the streams",
}

# Output a command's doc promises, by the command's text: each string must be in the doc (its
# comment, or output the doc shows for it: so the doc and this table agree) and in what the
# command prints. A frame in a comment is promised without being listed.
PROMISES: dict[str, tuple[str, ...]] = {
    # docs/wireshark.md's walkthrough: the dissector decodes the proxy's capture of `point 30 -45`
    "tshark -X lua_script:topgimbal.lua -r session.pcapng": (
        "TOP 66 GAM yaw_pitch_angle yaw=30.0 yaw_speed=9.9 pitch=-45.0 pitch_speed=9.9",
    ),
    "topgimbal sim --model SIP --serial pty --state sip.json --faults drop=0.1,delay_s=0.02 --seed 3": (
        "serial:///dev/pts/",
    ),
    "topgimbal sim --model C12 --udp 127.0.0.1:0": ("udp://127.0.0.1:",),
    "topgimbal decode '#TPUG6wGAYEF073288'": ("'88'", "'48'"),
    "topgimbal sim --model C12 --video": ("/stream=1", "/stream=2"),
    "topgimbal sim --model C12 --udp 127.0.0.1:0 --video --video-port 0": ("rtsp://127.0.0.1:", "/stream=1"),
}
# Documented exit status other than 0, by the command's text, with the doc's reason.
EXIT_STATUS: dict[str, int] = {
    "topgimbal decode '#TPUG6wGAYEF073288'": 1,  # "says what is wrong": a bad frame fails
}
# Shorter runs of the same command: the documented value only makes the test slower.
SHORTER: dict[tuple[str, str], str] = {
    ("--seconds", "10"): "1",
    ("--count", "100"): "5",
}
# Option values that are data for the device or filters on a file, not addresses anything is
# sent to: they may keep a documented non-loopback address.
DATA_ADDRESS_OPTIONS = {
    "--gateway": "a network setting written to the (simulated) camera",
    "--address": "a filter on the packets of a capture file",
    "--allow-host": "a host name the console accepts requests for",
}
# What an interactive command is answered on its terminal.
ANSWERS: dict[str, str] = {"net set": "y\n"}

MEDIA_PORT = "8090"  # docs/geotag.md's `sim --media-port 8090`: the test's sim picks a free one
URL_RE = re.compile(r"\b(udp|tcp)://([^/:\s?]+|\[[^\]]+\]):(\w+)")
SERIAL_RE = re.compile(r"(serial://)?(/dev/tty\w+)")
IPV4_RE = re.compile(r"\b(\d{1,3}\.\d{1,3}\.\d{1,3}\.\d{1,3})\b")
DOC_PORT_MODEL = {"9003": "SIP", "9004": "SIP"}
DAEMONS = {"sim", "proxy", "console", "mavlink", "zenoh", "video"}


# -- extraction ------------------------------------------------------------------------------------


@dataclass(frozen=True)
class Example:
    doc: str  # path relative to the repository
    line: int  # where the command starts in the doc
    block: int  # which shell block of the doc
    text: str  # the command as written, continuations joined, without its comment
    comment: str  # its comment (and comment lines continuing it)
    output: str = ""  # a console block's output lines after a `$ ` command

    @property
    def argv(self) -> list[str]:
        return shlex.split(self.text)

    @property
    def label(self) -> str:
        return f"{self.doc}:{self.line}: {self.text}"


def _split_comment(line: str) -> tuple[str, str]:
    """Code and comment of one shell line: `#` starts a comment at a word start outside quotes."""
    quote = ""
    for i, ch in enumerate(line):
        if quote:
            if ch == quote:
                quote = ""
        elif ch in "'\"":
            quote = ch
        elif ch == "#" and (i == 0 or line[i - 1].isspace()):
            return line[:i].rstrip(), line[i + 1 :].strip()
    return line.rstrip(), ""


def _alternatives(code: str) -> list[str]:
    """`record start|stop|status` is three commands; a `|` between words is a pipeline."""
    unquoted = re.sub(r"'[^']*'|\"[^\"]*\"", "", code)
    if re.search(r"\s\|\s", unquoted):
        return [code]  # a pipeline: not run, so NOT_RUN must list it
    match = re.search(r"(?<=\s)([\w.-]+(?:\|[\w.-]+)+)(?=\s|$)", unquoted)
    if match is None:
        return [code]
    return [code.replace(match.group(1), alt, 1) for alt in match.group(1).split("|")]


def _blocks(text: str) -> Iterator[tuple[int, str, list[str]]]:
    lines = text.splitlines()
    i = 0
    while i < len(lines):
        m = re.match(r"^```(\w+)\s*$", lines[i])
        if m is None:
            i += 1
            continue
        start, lang = i + 1, m.group(1)
        i += 1
        while i < len(lines) and not lines[i].startswith("```"):
            i += 1
        if lang in SHELL_LANGS:
            yield start + 1, lang, lines[start:i]
        i += 1


def extract(path: Path) -> list[Example]:
    doc = str(path.relative_to(ROOT))
    examples: list[Example] = []
    for block, (first_line, lang, lines) in enumerate(_blocks(path.read_text(encoding="utf-8"))):
        pending: list[tuple[int, str, str]] = []  # (line, code, comment) of this block
        output: dict[int, list[str]] = {}
        joined, joined_line = "", 0
        for offset, raw in enumerate(lines):
            lineno = first_line + offset
            if lang == "console" and not raw.startswith("$ ") and not joined:
                if pending and raw.strip():
                    output.setdefault(len(pending) - 1, []).append(raw)
                continue
            raw = raw[2:] if raw.startswith("$ ") else raw
            code, comment = _split_comment(raw)
            if not joined and not code.strip():
                if comment and pending:  # a comment line continuing the previous command's
                    ln, c, prev = pending[-1]
                    pending[-1] = (ln, c, f"{prev} {comment}".strip())
                continue
            if not joined:
                joined_line = lineno
            if code.endswith("\\"):
                joined += code[:-1].strip() + " "
                continue
            pending.append((joined_line, (joined + code.strip()).strip(), comment))
            joined = ""
        for index, (ln, code, comment) in enumerate(pending):
            for alt in _alternatives(code):
                examples.append(Example(doc, ln, block, alt, comment, "\n".join(output.get(index, []))))
    return examples


EXAMPLES = [ex for path in DOCS for ex in extract(path)]


def _runs(ex: Example) -> bool:
    return ex.argv[0] == "topgimbal" or (ex.text not in NOT_RUN and _other_runner(ex) is not None)


def _other_runner(ex: Example) -> list[str] | None:
    """Commands beside topgimbal that a test can run: tshark, curl, the C code generator's check,
    the C example's build and run (in a copy of the tree's c/ and examples/)."""
    argv = ex.argv
    if (
        argv[0] == "python"
        and argv[1:3] in (["-m", "topgimbal.tools.cgen"], ["-m", "topgimbal.tools.regen"])
        and ("--check" in argv or "--list" in argv)
    ):
        return [sys.executable, *argv[1:]]
    if argv[0] in ("tshark", "curl", "examples/c/point_camera") or argv == ["make", "-C", "examples/c"]:
        return argv
    return None


# -- simulators and the per-doc session -----------------------------------------------------------


class Sims:
    """One simulator per model, shared by all docs: C12 and SIP on UDP (SIP also on a pty serial
    line), C20 on TCP (the documented transports)."""

    def __init__(self) -> None:
        self.sims: dict[str, BackgroundSimulator] = {}
        self.lock = threading.Lock()

    def get(self, model: str) -> BackgroundSimulator:
        with self.lock:
            if model not in self.sims:
                listen: dict[str, Any] = {"udp": [("127.0.0.1", 0)]}
                if model == "SIP":
                    listen["serial"] = ["pty"]
                if model == "C20":
                    listen = {"tcp": [("127.0.0.1", 0)]}
                self.sims[model] = BackgroundSimulator(model, seed=5, listen=listen).start()
            return self.sims[model]

    def url(self, model: str, kind: str) -> str:
        endpoints = dict(self.get(model).endpoints)
        return endpoints.get(kind) or endpoints["udp"]

    def stop(self) -> None:
        for bg in self.sims.values():
            bg.stop()


@dataclass
class Daemon:
    ex: Example
    argv: list[str]
    proc: subprocess.Popen[str]
    outputs: set[str]  # files it writes (--pcap, --log)
    lines: list[str] = field(default_factory=list)
    eof: bool = False
    cond: threading.Condition = field(default_factory=threading.Condition)

    def read(self) -> None:
        assert self.proc.stdout is not None
        for line in self.proc.stdout:
            with self.cond:
                self.lines.append(line.rstrip("\n"))
                self.cond.notify_all()
        with self.cond:
            self.eof = True
            self.cond.notify_all()

    def wait_for(self, pattern: str, nth: int = 0, timeout_s: float = RUN_TIMEOUT_S) -> re.Match[str]:
        deadline = time.monotonic() + timeout_s
        with self.cond:
            while True:
                found = [m for m in (re.search(pattern, line) for line in self.lines) if m]
                if len(found) > nth:
                    return found[nth]
                left = deadline - time.monotonic()
                if self.eof or left <= 0:
                    raise AssertionError(
                        f"{self.ex.label}: never printed {pattern!r} (exit {self.proc.poll()}):\n"
                        + "\n".join(self.lines)
                    )
                self.cond.wait(min(left, 0.5))

    def stop(self) -> None:
        if self.proc.poll() is None:
            self.proc.send_signal(signal.SIGINT)
        try:
            rc = self.proc.wait(RUN_TIMEOUT_S)
        except subprocess.TimeoutExpired:
            self.proc.kill()
            raise AssertionError(f"{self.ex.label}: did not stop on Ctrl-C") from None
        # Ctrl-C is how the docs stop these: a clean exit, files flushed.
        assert rc == 0, f"{self.ex.label}: exit {rc} on Ctrl-C:\n" + "\n".join(self.lines)


@dataclass
class Listener:
    """A port a daemon of the doc listens on, instead of the documented one."""

    daemon: Daemon
    scheme: str
    nth: int  # the nth URL of this scheme the daemon prints


class Session:
    """The commands of one doc, in order, in a directory of their own (files flow between them)."""

    def __init__(self, cwd: Path) -> None:
        self.sims = Sims()  # a doc's own: another doc's commands do not move its gimbal
        self.cwd = cwd
        self.daemons: list[Daemon] = []
        self.listeners: dict[tuple[str, str], Listener] = {}  # (scheme, documented port)
        self.last_sim: Listener | None = None
        self.ports: dict[str, str] = {}  # documented port -> actual, for filters on captures
        self.ptys: list[int] = []
        self.sockets: list[socket.socket] = []
        self._pending: list[tuple[str, str, int]] = []  # listeners of the command being set up
        self._heartbeat_socket: socket.socket | None = None  # where its mavlink udpout points
        self.zenoh_ports: dict[str, int] = {}  # a doc's Zenoh address -> the free port used for it
        self._tcp_in: int | None = None  # its mavlink tcpin port
        self._console: str | None = None  # the console curl talks to
        self._media: Daemon | None = None  # the sim whose --media-port the doc's http://127.0.0.1:8090/ is
        self._last_pty_master = -1  # the other end of the last serial line handed to a command

    # -- substitution ----------------------------------------------------------------------------

    def _resolve(self, scheme: str, port: str, model: str | None) -> str:
        listener = self.listeners.get((scheme, port))
        if port == "PORT":
            listener = self.last_sim
        if listener is not None:
            m = listener.daemon.wait_for(rf"\b{scheme}://127\.0\.0\.1:(\d+)", listener.nth)
            self.ports[port] = m.group(1)
            return f"{scheme}://127.0.0.1:{m.group(1)}"
        model = model or DOC_PORT_MODEL.get(port) or ("C20" if scheme == "tcp" else "C12")
        url = self.sims.url(model, scheme)
        assert url.startswith(f"{scheme}://"), f"no {scheme} simulator for {model}"
        self.ports[port] = url.rsplit(":", 1)[1]
        return url

    def _pty(self) -> str:
        master, slave = pty.openpty()
        tty.setraw(master)  # bytes as they are: no echo, no line discipline
        self.ptys += [master, slave]
        self._last_pty_master = master
        return os.ttyname(slave)

    def _serial_device(self, model: str | None) -> str:
        url = self.sims.url(model or "SIP", "serial")
        assert url.startswith("serial:///dev/"), f"no serial simulator for {model}: {url}"
        return url[len("serial://") :].split("?")[0]

    def substitute(self, ex: Example) -> list[str]:
        argv = ex.argv
        model = argv[argv.index("--model") + 1] if "--model" in argv else None
        sub = _subcommand(argv)
        out: list[str] = [str(EXE)]
        listening_opts = {"sim": ("--udp", "--tcp"), "proxy": ("--listen",), "console": ("--listen",)}.get(sub, ())
        i = 1
        while i < len(argv):
            tok = argv[i]
            nxt = argv[i + 1] if i + 1 < len(argv) else None
            if nxt is not None and (tok, nxt) in SHORTER:
                out += [tok, SHORTER[(tok, nxt)]]
                i += 2
                continue
            if tok in DATA_ADDRESS_OPTIONS and nxt is not None:
                out += [tok, nxt]
                i += 2
                continue
            if tok in listening_opts and nxt is not None:
                out += [tok, self._listen(sub, tok, nxt)]
                i += 2
                continue
            if sub == "sim" and tok == "--serial" and nxt not in (None, "pty"):
                out += [tok, "pty"]
                i += 2
                continue
            if sub == "sim" and tok in ("--video-port", "--media-port"):
                out += [tok, "0"]
                i += 2
                continue
            if sub == "console" and tok == "--port":
                out += [tok, "0"]
                i += 2
                continue
            zenoh_opt = (sub, tok) in (("zenoh", "--listen"), ("zenoh", "--connect"), ("console", "--zenoh"))
            if zenoh_opt and nxt is not None:
                out += [tok, self._zenoh_endpoint(nxt)]  # tcp/127.0.0.1:7447 may be taken
                i += 2
                continue
            if sub == "mavlink" and tok == "--mavlink" and nxt is not None:
                out += [tok, self._mavlink_endpoint(nxt)]
                i += 2
                continue
            out.append(self._destination(tok, model))
            i += 1
        if sub == "sim":
            if not {"--udp", "--tcp", "--serial"} & set(argv):  # the documented ports: a camera's
                out += ["--udp", "127.0.0.1:0"]
                self._add_listener("udp", "documented")
            if "--video" in argv and "--video-port" not in argv:
                out += ["--video-port", "0"]
        if sub == "console" and "--port" not in argv:
            out += ["--port", "0"]  # 8080 may be taken; the console would fall back anyway
        if sub == "monitor" and "--count" not in argv:
            out += ["--count", "3"]  # its own bound instead of Ctrl-C
        if sub == "decode" and "--port" in argv:
            j = out.index("--port") + 1
            out[j] = self.ports.get(out[j], out[j])
        return out

    def _add_listener(self, scheme: str, doc_port: str) -> None:
        nth = sum(1 for s, _, _ in self._pending if s == scheme)
        self._pending.append((scheme, doc_port, nth))

    def _listen(self, sub: str, opt: str, value: str) -> str:
        if sub == "sim":
            scheme = opt[2:]
            port = value.rpartition(":")[2]
            self._add_listener(scheme, port)
            return "127.0.0.1:0"
        m = URL_RE.match(value)
        if m:
            self._add_listener(m.group(1), m.group(3))
            return f"{m.group(1)}://127.0.0.1:0"
        sm = SERIAL_RE.match(value)
        assert sm, f"cannot listen on {value!r} in a test"
        return f"serial://{self._pty()}" + value[sm.end() :]

    def _zenoh_endpoint(self, value: str) -> str:
        proto, _, address = value.partition("/")
        assert address.rpartition(":")[0] in LOOPBACK, f"Zenoh endpoint {value!r} is not loopback"
        if address not in self.zenoh_ports:
            with socket.socket() as s:
                s.bind(("127.0.0.1", 0))
                self.zenoh_ports[address] = s.getsockname()[1]
        return f"{proto}/127.0.0.1:{self.zenoh_ports[address]}"

    def _mavlink_endpoint(self, value: str) -> str:
        kind = value.partition(":")[0]
        if kind == "udpout":
            sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
            sock.bind(("127.0.0.1", 0))
            sock.settimeout(RUN_TIMEOUT_S)
            self.sockets.append(sock)
            self._heartbeat_socket = sock
            return f"udpout:127.0.0.1:{sock.getsockname()[1]}"
        if kind in ("tcpin", "udpin", "tcp"):
            with socket.socket() as s:
                s.bind(("127.0.0.1", 0))
                port = s.getsockname()[1]
            if kind == "tcpin":
                self._tcp_in = port
            return f"{kind}:127.0.0.1:{port}"
        device, _, baud = value.partition(",")
        assert device.startswith("/dev/"), f"unknown MAVLink endpoint {value!r}"
        return f"{self._pty()},{baud}" if baud else self._pty()

    def _destination(self, tok: str, model: str | None) -> str:
        if tok == "PORT":  # `127.0.0.1 PORT`: the simulator's port
            return self._resolve("udp", "PORT", model).rsplit(":", 1)[1]
        tok = URL_RE.sub(lambda m: self._resolve(m.group(1), m.group(3), model), tok)
        if SERIAL_RE.search(tok):
            tok = SERIAL_RE.sub(lambda m: (m.group(1) or "") + self._serial_device(model), tok)
        if tok == "0.0.0.0":
            return "127.0.0.1"
        if tok.startswith("http://127.0.0.1:8080/"):
            return self._console_url() + tok.split(":8080/", 1)[1]
        if tok.startswith(f"http://127.0.0.1:{MEDIA_PORT}/") and self._media is not None:
            # the documented media port: the URL the doc's `sim --media-port` printed
            return self._media.wait_for(r"(http://127\.0\.0\.1:\d+/)").group(1) + tok.split(f":{MEDIA_PORT}/", 1)[1]
        return tok

    def _console_url(self) -> str:
        """The doc's earlier examples ran a console on 8080: one of its own, for curl."""
        if self._console is None:
            ex = Example("(test)", 0, -1, "topgimbal console --sim C12 --port 0", "")
            pending, self._pending = self._pending, []
            daemon = self._start(ex, [str(EXE), "console", "--sim", "C12", "--port", "0"])
            self._pending = pending
            self._console = daemon.wait_for(r"open (http://127\.0\.0\.1:\d+/)").group(1)
            # Traffic for the capture: the console polls its camera once it has a page open.
            urllib.request.urlopen(self._console, timeout=RUN_TIMEOUT_S).read()
        return self._console

    # -- running ---------------------------------------------------------------------------------

    def _start(self, ex: Example, argv: list[str]) -> Daemon:
        proc = subprocess.Popen(
            argv, cwd=self.cwd, env=_env(), stdin=subprocess.DEVNULL, stdout=subprocess.PIPE,
            stderr=subprocess.STDOUT, text=True, start_new_session=True, preexec_fn=_ctrl_c_as_in_a_terminal,
        )  # fmt: skip
        outputs = {argv[j + 1] for j, t in enumerate(argv[:-1]) if t in ("--pcap", "--log")}
        daemon = Daemon(ex, argv, proc, outputs)
        if "--media-port" in argv:
            self._media = daemon
        threading.Thread(target=daemon.read, daemon=True).start()
        self.daemons.append(daemon)
        for scheme, port, nth in self._pending:
            listener = Listener(daemon, scheme, nth)
            self.listeners[(scheme, port)] = listener
            if _subcommand(ex.argv) == "sim":
                self.last_sim = listener
        self._pending = []
        return daemon

    def run(self, ex: Example) -> None:
        self._pending, self._heartbeat_socket, self._tcp_in = [], None, None
        argv = self.substitute(ex) if ex.argv[0] == "topgimbal" else self._other(ex)
        _assert_loopback_only(argv)
        for daemon in list(self.daemons):  # it reads what a running one writes: stop that first
            if daemon.outputs & set(argv):
                daemon.stop()
                self.daemons.remove(daemon)
        promised = list(PROMISES.get(ex.text, ()))
        promised += re.findall(r"#(?:TP|tp)\w+", ex.comment)
        promised += [line.strip() for line in ex.output.splitlines()]
        doc_text = (ROOT / ex.doc).read_text(encoding="utf-8") if (ROOT / ex.doc).is_file() else ""
        for p in promised:
            assert p in ex.comment or p in ex.output or p in doc_text, (
                f"{ex.label}: PROMISES says {p!r}, the doc does not"
            )
        sub = _subcommand(ex.argv)
        if sub in DAEMONS and ex.argv[0] == "topgimbal":
            daemon = self._start(ex, argv)
            self._check_up(sub, ex, daemon)
            for p in promised:  # it prints as it goes: wait for each
                daemon.wait_for(re.escape(p))
        else:
            text = "\n".join(self._run_once(ex, argv))
            for p in promised:
                assert p in text, f"{ex.label}: the doc promises {p!r}; printed:\n{text}"

    def _other(self, ex: Example) -> list[str]:
        argv = _other_runner(ex)
        assert argv is not None
        return [self._destination(tok, None) for tok in argv]

    def _run_once(self, ex: Example, argv: list[str]) -> list[str]:
        answer = next((a for key, a in ANSWERS.items() if key in ex.text), None)
        stdin: Any = subprocess.DEVNULL
        if answer is not None:  # it asks on a terminal
            master, slave = pty.openpty()
            self.ptys += [master, slave]
            os.write(master, answer.encode())
            stdin = slave
        try:
            done = subprocess.run(
                argv, cwd=self.cwd, env=_env(), stdin=stdin, capture_output=True, text=True, timeout=RUN_TIMEOUT_S
            )
        except subprocess.TimeoutExpired as exc:
            raise AssertionError(f"{ex.label}: still running after {RUN_TIMEOUT_S} s") from exc
        expected = EXIT_STATUS.get(ex.text, 0)
        assert done.returncode == expected, (
            f"{ex.label}\nran {shlex.join(argv)}\nexit {done.returncode}, documented {expected}\n"
            f"{done.stdout}{done.stderr}"
        )
        return (done.stdout + done.stderr).splitlines()

    def _check_up(self, sub: str, ex: Example, daemon: Daemon) -> None:
        argv = daemon.argv
        if sub == "sim":
            daemon.wait_for(r"^(udp|tcp|serial)://")
            if "--video" in argv:
                daemon.wait_for(r"video at rtsp://127\.0\.0\.1:\d+/")
        elif sub == "proxy":
            m = daemon.wait_for(r"topgimbal proxy: (\S+) -> ")
            if URL_RE.match(m.group(1)):  # a frame through it, and its reply back
                scheme, rest = m.group(1).split("://")
                host, port = rest.rsplit(":", 1)
                self._probe(ex, scheme, (host, int(port)))
            elif m.group(1).startswith("serial://"):  # a ground station on the line's other end
                self._probe_serial(ex, self._last_pty_master)
        elif sub == "console":
            url = daemon.wait_for(r"open (http://127\.0\.0\.1:\d+/)").group(1)
            with urllib.request.urlopen(url, timeout=RUN_TIMEOUT_S) as page:
                assert page.status == 200 and b"<html" in page.read().lower(), ex.label
        elif sub == "video":  # `video relay`: up once it names its source and target (the source may be absent)
            daemon.wait_for(r"^video relay: rtsp://\S+ -> udp://127\.0\.0\.1:\d+ ")
        elif sub == "zenoh":
            daemon.wait_for(r"^zenoh: serving \d+ cameras on tcp/127\.0\.0\.1:\d+")
        elif sub == "mavlink":
            daemon.wait_for(r"^mavlink bridge: ")
            sock = self._heartbeat_socket
            if sock is not None:  # MAVLink 2 frames (0xFD) arrive where udpout points
                data, _ = sock.recvfrom(4096)
                assert data[:1] == b"\xfd", f"{ex.label}: not MAVLink 2: {data!r}"
            if self._tcp_in is not None:
                socket.create_connection(("127.0.0.1", self._tcp_in), timeout=RUN_TIMEOUT_S).close()

    def _probe_serial(self, ex: Example, fd: int) -> None:
        frames = [encode(dialect, "VER", read=True).to_bytes() for dialect in ("skydroid", "topotek")]
        os.write(fd, b"".join(frames))
        readable, _, _ = select.select([fd], [], [], RUN_TIMEOUT_S)
        reply = os.read(fd, 4096) if readable else b""
        assert reply.startswith((b"#TP", b"#tp")), f"{ex.label}: no reply on the serial line: {reply!r}"

    def _probe(self, ex: Example, scheme: str, addr: tuple[str, int]) -> None:
        # Whichever camera is behind it answers its own dialect's query and ignores the other.
        frames = [encode(dialect, "VER", read=True).to_bytes() for dialect in ("skydroid", "topotek")]
        if scheme == "tcp":
            with socket.create_connection(addr, timeout=RUN_TIMEOUT_S) as s:
                s.sendall(b"".join(frames))
                reply = s.recv(4096)
            assert reply.startswith((b"#TP", b"#tp")), f"{ex.label}: {reply!r}"
            return
        with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as s:
            s.settimeout(5.0)
            for _ in range(5):  # UDP: the first datagram may go before the camera side is open
                for frame in frames:
                    s.sendto(frame, addr)
                try:
                    reply, _ = s.recvfrom(4096)
                except TimeoutError:
                    continue
                assert reply.startswith((b"#TP", b"#tp")), f"{ex.label}: {reply!r}"
                return
        raise AssertionError(f"{ex.label}: no reply through the proxy at {addr}")

    def close(self) -> None:
        errors = []
        for daemon in self.daemons:
            try:
                daemon.stop()
            except AssertionError as exc:
                errors.append(str(exc))
        for fd in self.ptys:
            os.close(fd)
        for sock in self.sockets:
            sock.close()
        self.daemons, self.ptys, self.sockets = [], [], []
        self.listeners, self.last_sim = {}, None  # its documented ports are free again
        self._console = None
        assert not errors, "\n".join(errors)

    def stop_sims(self) -> None:
        self.sims.stop()


def _subcommand(argv: list[str]) -> str:
    i = 1
    while i < len(argv) and argv[i].startswith("-"):
        i += 2 if argv[i] in ("--url", "--model") else 1
    return argv[i] if i < len(argv) else ""


def _ctrl_c_as_in_a_terminal() -> None:
    """In the daemon before it starts: Ctrl-C as a terminal delivers it. A shell runs a background
    job (a CI script started with `&`, nohup) with SIGINT ignored, and children inherit that; the
    docs' commands are typed in a terminal, where Ctrl-C stops them."""
    signal.signal(signal.SIGINT, signal.SIG_DFL)
    # And it dies with the test process: a worker killed on its timeout never runs close(), and a
    # daemon in its own session outlived it (a console found running an hour later, on a loaded
    # machine a noisy neighbour of every run after). Linux's PR_SET_PDEATHSIG (1): SIGKILL then.
    with contextlib.suppress(OSError, AttributeError):
        ctypes.CDLL(None, use_errno=True).prctl(1, signal.SIGKILL, 0, 0, 0)


def _env() -> dict[str, str]:
    env = {k: v for k, v in os.environ.items() if not k.startswith("TOPGIMBAL_")}
    env["PATH"] = f"{EXE.parent}{os.pathsep}{env.get('PATH', '')}"
    return env


def _assert_loopback_only(argv: list[str]) -> None:
    for j, tok in enumerate(argv):
        if j > 0 and argv[j - 1] in DATA_ADDRESS_OPTIONS:
            continue
        for m in URL_RE.finditer(tok):
            assert m.group(2) in LOOPBACK, f"not loopback: {tok!r} in {shlex.join(argv)}"
        for m in re.finditer(r"\b(?:udpout|udpin|tcpin|tcp):(?!//)([^:,\s]+):\d+", tok):
            assert m.group(1) in LOOPBACK, f"not loopback: {tok!r} in {shlex.join(argv)}"
        for m in IPV4_RE.finditer(tok):
            assert m.group(1) == "127.0.0.1", f"not loopback: {tok!r} in {shlex.join(argv)}"
        assert not re.search(r"\b(CAMERA|HOST)\b", tok), f"placeholder left: {tok!r}"
        assert not tok.startswith("/dev/tty") and "///dev/tty" not in tok, f"a real serial device: {tok!r}"


def _capture_from_the_lan(path: Path) -> None:
    """docs/wireshark.md decodes "capture.pcap", any capture from a camera's LAN: a C12 on
    192.0.2.11:5000 and a SIP on 192.0.2.10:9003 here (written to a file; nothing is sent)."""
    writer = CaptureWriter(path)
    host = ("192.0.2.1", 50000)
    for camera, dialect in ((("192.0.2.11", 5000), "skydroid"), (("192.0.2.10", 9003), "topotek")):
        writer.udp(host, camera, encode(dialect, "VER", read=True).to_bytes())
    writer.close()


# -- the tests -------------------------------------------------------------------------------------


@pytest.fixture(scope="module")
def results(tmp_path_factory: pytest.TempPathFactory) -> dict[str, dict[str, str]]:
    """Run every doc's examples (docs in parallel, each doc's in order): doc -> text -> error."""
    outcome: dict[str, dict[str, str]] = {}

    # The doc with the most examples first: it is the longest chain of commands.
    docs = sorted({ex.doc for ex in EXAMPLES}, key=lambda d: -sum(ex.doc == d for ex in EXAMPLES))
    cwds = {doc: tmp_path_factory.mktemp(Path(doc).stem) for doc in docs}  # not thread-safe

    def run_doc(doc: str) -> None:
        cwd = cwds[doc]
        _capture_from_the_lan(cwd / "capture.pcap")
        for tree in ("c", "examples", "contrib"):  # what examples name by relative path
            shutil.copytree(ROOT / tree, cwd / tree, ignore=shutil.ignore_patterns("build", "point_camera"))
        session = Session(cwd)
        errors = outcome.setdefault(doc, {})
        block = None
        for ex in (e for e in EXAMPLES if e.doc == doc and _runs(e)):
            if ex.block != block:
                try:
                    session.close()  # the previous block's daemons
                except AssertionError as exc:
                    errors[f"(block {block})"] = str(exc)
                block = ex.block
            try:
                session.run(ex)
                errors[ex.text] = ""
            except AssertionError as exc:
                errors[ex.text] = str(exc)
        try:
            session.close()
        except AssertionError as exc:
            errors[f"(block {block})"] = str(exc)
        finally:
            session.stop_sims()

    with ThreadPoolExecutor(max_workers=3) as pool:
        list(pool.map(run_doc, docs))
    return outcome


def test_examples_are_found() -> None:
    docs = {ex.doc for ex in EXAMPLES}
    assert {"README.md", "docs/client.md", "docs/wireshark.md", "docs/console.md"} <= docs
    assert len(EXAMPLES) > 60
    assert any(ex.text.endswith("record stop") for ex in EXAMPLES)  # alternatives expanded


def test_every_command_is_run_or_listed() -> None:
    neither = [ex.label for ex in EXAMPLES if not _runs(ex) and ex.text not in NOT_RUN]
    assert not neither, "run these in this test or list them in NOT_RUN with a reason:\n" + "\n".join(neither)
    stale = set(NOT_RUN) - {ex.text for ex in EXAMPLES}
    assert not stale, f"NOT_RUN lists commands no doc has any more: {stale}"


@pytest.mark.parametrize("doc", sorted({ex.doc for ex in EXAMPLES if _runs(ex)}))
def test_doc_examples_run(doc: str, results: dict[str, dict[str, str]]) -> None:
    ran = results[doc]
    expected = [ex.text for ex in EXAMPLES if ex.doc == doc and _runs(ex)]
    assert [t for t in expected if t not in ran] == [], "not run"
    failed = {text: err for text, err in ran.items() if err}
    assert not failed, "\n\n".join(f"{text}\n{err}" for text, err in failed.items())


def test_loopback_guard_refuses_other_addresses() -> None:
    for argv in (
        ["topgimbal", "--url", "udp://192.168.144.25:5000", "info"],
        ["topgimbal", "mavlink", "--mavlink", "tcpin:0.0.0.0:5760"],
        ["topgimbal", "proxy", "--to", "serial:///dev/ttyUSB0"],
        ["topgimbal", "console", "--url", "udp://CAMERA:9003"],
    ):
        with pytest.raises(AssertionError):
            _assert_loopback_only(argv)
    _assert_loopback_only(["topgimbal", "net", "set", "--gateway", "192.168.144.1"])


def test_extraction_handles_comments_prompts_and_continuations(tmp_path: Path) -> None:
    doc = tmp_path / "x.md"
    doc.write_text(
        "```console\n$ topgimbal decode '#TPUD2rREC003E'   # a frame\n#TPUD2rREC003E  ok\n```\n"
        "```sh\ntopgimbal a \\\n    --b 1   # one\n                   # two\ntopgimbal r x|y\n```\n",
        encoding="utf-8",
    )
    global ROOT
    saved, ROOT = ROOT, tmp_path
    try:
        got = [(e.text, e.comment, e.output) for e in extract(doc)]
    finally:
        ROOT = saved
    assert got == [
        ("topgimbal decode '#TPUD2rREC003E'", "a frame", "#TPUD2rREC003E  ok"),
        ("topgimbal a --b 1", "one two", ""),
        ("topgimbal r x", "", ""),
        ("topgimbal r y", "", ""),
    ]


@pytest.mark.parametrize(
    ("text", "comment", "why"),
    [
        # README's comment before it was fixed: the frame needs speed_deg_s=5.
        ("topgimbal encode GAY yaw_deg=-50 --dialect skydroid", "#TPUG6wGAYEC78324D", "promises"),
        # A bad frame fails; a doc that does not say so (no EXIT_STATUS entry) is wrong.
        ("topgimbal decode '#TPUG6wGAYEF073288' --json", "", "documented 0"),
        # docs/client.md's range before it was fixed: a SIP without ALT has no distance.
        ("topgimbal --url udp://127.0.0.1:9003 --model SIP range", "", "documented 0"),
    ],
)
def test_a_wrong_example_fails(tmp_path: Path, text: str, comment: str, why: str) -> None:
    session = Session(tmp_path)
    try:
        with pytest.raises(AssertionError, match=why):
            session.run(Example("x.md", 1, 0, text, comment))
    finally:
        session.close()
        session.stop_sims()
