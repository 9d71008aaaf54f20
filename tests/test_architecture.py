"""docs/architecture.md's rules, checked: imports point down the layers, and the protocol core
imports nothing outside the standard library."""

from __future__ import annotations

import ast
import sys
from pathlib import Path

import pytest

pytestmark = pytest.mark.loopback

PKG = Path(__file__).resolve().parents[1] / "src" / "topgimbal"

# Leaf modules every layer may import: the exceptions, the throttled warning log, the one clock,
# the escaping of a peer's text for the log, the JSON Lines writer and the servers' peer table.
SHARED_LEAVES = (
    "errors", "logthrottle", "_lazy", "_moved", "clock", "logtext", "jsonl", "peers", "timeouts", "inputfile", "periodic",
)  # fmt: skip

# What each layer may import from inside topgimbal (besides itself and SHARED_LEAVES).
ALLOWED = {
    "_speedups": set(),  # the optional C fast path: a leaf the protocol core may use
    "protocol": {"_speedups"},  # the fast path, used only where it is built (stdlib-only without it)
    "transport": {"protocol", "_speedups"},  # _speedups: recvmmsg for the fleet server's shared UDP socket
    "client": {"protocol", "transport", "geo"},  # geo: cam.locate() and the optics; the stream table: protocol
    "geo": set(),  # pure geolocation (terrain, laser, flat ground); dem.py imports rasterio on use
    "sim": {"protocol", "geo", "transport"},  # geo: the laser's truth (--terrain); transport.memory: listen_memory
    "console": {
        "protocol",
        "client",
        "sim",
        "video",
        "wire",
        "transport",
        "geo",
        "autopilot",
    },  # sim: `--sim`; wire: pcap, --proxy; geo: wraps; autopilot: --autopilot reads GLOBAL_POSITION_INT as the bridge does
    "video": {"protocol", "sim", "geo"},  # renders the simulator's state; relays any camera's RTSP; geo: angle wraps
    "tools": {"protocol", "client", "sim", "console", "_speedups", "video"},
    # MAVLink links: bytes to peers, signing, pymavlink's one import; they know no bridge
    "links": set(),
    # what the bridge hears from and asks of autopilots (vehicles, feeds, stream rates, reboots): it
    # reads pymavlink's messages from links and sends through a Sender it is given; it knows no bridge
    "autopilot": {"geo", "links"},
    # MAVLink camera definitions from the catalog, and their read-only HTTP server: no pymavlink
    "camdef": {"protocol"},
    "mavlink": {
        "protocol",
        "client",
        "track",
        "geo",
        "outputs",
        "links",
        "autopilot",
        "camdef",
    },  # track: --companion-tracking; geo: CAMERA_FOV_STATUS, the optics; outputs: what it feeds (RTP out too)
    # CoT, KLV, the recorder, RTP out: fed a Sighting; never MAVLink (issue 44). video: rtp_push
    "outputs": {"geo", "video", "protocol"},  # protocol: the stream table's VideoError
    "wire": {"protocol", "transport", "client"},  # client only for the JSONL traffic log format
    "fleet": {"protocol", "client"},  # the Zenoh fleet server: SDK clients on one session
    # the companion tracking loop: rates out; geo: wraps, the optics; video: rtsp_frames() only (the
    # RTSP decoder, imported when called)
    "track": {"protocol", "client", "video", "geo"},
    "cli": {
        "protocol",
        "client",
        "transport",
        "sim",
        "console",
        "tools",
        "mavlink",
        "wire",
        "video",
        "fleet",
        "track",
        "geo",
        "outputs",
        "links",
    },
}


def _imports(path: Path) -> list[str]:
    """Absolute module names imported by a file (relative imports resolved)."""
    tree = ast.parse(path.read_text(encoding="utf-8"))
    parts = list(path.relative_to(PKG.parent).with_suffix("").parts)
    if parts[-1] == "__init__":
        parts = parts[:-1]
    out = []
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            out += [a.name for a in node.names]
        elif isinstance(node, ast.ImportFrom):
            if node.level:
                base = parts[: len(parts) - node.level + (1 if path.name == "__init__.py" else 0)]
                out.append(".".join([*base, node.module] if node.module else base))
            elif node.module:
                out.append(node.module)
    return out


def test_layers_import_only_downwards() -> None:
    bad = []
    for layer, allowed in ALLOWED.items():
        for path in (PKG / layer).rglob("*.py"):
            for mod in _imports(path):
                if not mod.startswith("topgimbal."):
                    continue
                target = mod.split(".")[1]
                if target not in (layer, *SHARED_LEAVES) and target not in allowed:
                    bad.append(f"{path.relative_to(PKG)} imports {mod}")
    assert not bad, "\n".join(bad)


def test_protocol_core_is_standard_library_only() -> None:
    stdlib = sys.stdlib_module_names
    bad = []
    for path in (PKG / "protocol").rglob("*.py"):
        for mod in _imports(path):
            top = mod.split(".")[0]
            if top != "topgimbal" and top not in stdlib and top != "__future__":
                bad.append(f"{path.relative_to(PKG)} imports {mod}")
    assert not bad, "\n".join(bad)


# -- no import circles inside a package -------------------------------------------------------------

# Packages whose modules import each other in a circle today, named here so the check holds for every
# other package; each entry is a debt to pay off, not a licence (the lead closes this list).
CIRCLE_EXCEPTIONS: frozenset[str] = frozenset()


def _module_name(path: Path) -> str:
    parts = list(path.relative_to(PKG.parent).with_suffix("").parts)
    return ".".join(parts[:-1] if parts[-1] == "__init__" else parts)


def _is_type_checking(node: ast.If) -> bool:
    test = node.test
    return (isinstance(test, ast.Name) and test.id == "TYPE_CHECKING") or (
        isinstance(test, ast.Attribute) and test.attr == "TYPE_CHECKING"
    )


def _module_level_imports(path: Path, modules: set[str]) -> set[str]:
    """Modules of `modules` that `path` imports when it is imported: statements at module level
    (also inside module-level if / try blocks), not inside functions, not under TYPE_CHECKING. A
    `from package import name` counts for the package and, when `name` is a module, for it too."""
    tree = ast.parse(path.read_text(encoding="utf-8"))
    here = _module_name(path).split(".")
    package = here if path.name == "__init__.py" else here[:-1]
    out: set[str] = set()

    def visit(body: list[ast.stmt]) -> None:
        for node in body:
            if isinstance(node, ast.If):
                if not _is_type_checking(node):
                    visit(node.body)
                visit(node.orelse)
            elif isinstance(node, ast.Try):
                for block in (node.body, node.orelse, node.finalbody, *(h.body for h in node.handlers)):
                    visit(block)
            elif isinstance(node, ast.Import):
                out.update(a.name for a in node.names)
            elif isinstance(node, ast.ImportFrom):
                base = package[: len(package) - node.level + 1] if node.level else []
                mod = ".".join([*base, *(node.module.split(".") if node.module else [])])
                for a in node.names:
                    # A submodule named in the import is what it imports; a name defined in the
                    # package's __init__ imports the package (whose parents load first anyway).
                    out.add(f"{mod}.{a.name}" if f"{mod}.{a.name}" in modules else mod)

    visit(tree.body)
    out.discard(_module_name(path))  # `from . import x` in a package's __init__
    return out & modules


def _circles(graph: dict[str, set[str]]) -> list[list[str]]:
    """Strongly connected components of more than one module."""
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    stack: list[str] = []
    on_stack: set[str] = set()
    found: list[list[str]] = []

    def strongconnect(v: str) -> None:
        index[v] = low[v] = len(index)
        stack.append(v)
        on_stack.add(v)
        for w in sorted(graph.get(v, ())):
            if w not in index:
                strongconnect(w)
                low[v] = min(low[v], low[w])
            elif w in on_stack:
                low[v] = min(low[v], index[w])
        if low[v] == index[v]:
            component = []
            while True:
                w = stack.pop()
                on_stack.discard(w)
                component.append(w)
                if w == v:
                    break
            if len(component) > 1:
                found.append(sorted(component))

    for v in sorted(graph):
        if v not in index:
            strongconnect(v)
    return found


def _package_circles() -> dict[str, list[list[str]]]:
    out: dict[str, list[list[str]]] = {}
    for package in sorted(p for p in PKG.iterdir() if (p / "__init__.py").exists()):
        files = list(package.rglob("*.py"))
        modules = {_module_name(f) for f in files}
        graph = {_module_name(f): _module_level_imports(f, modules) for f in files}
        circles = _circles(graph)
        if circles:
            out[package.name] = circles
    return out


def test_no_import_circles_inside_a_package() -> None:
    circles = _package_circles()
    bad = {name: c for name, c in circles.items() if name not in CIRCLE_EXCEPTIONS}
    assert not bad, "\n".join(f"{name}: {' -> '.join(c)}" for name, cs in bad.items() for c in cs)
    paid = sorted(CIRCLE_EXCEPTIONS - circles.keys())
    assert not paid, f"no circle left in {', '.join(paid)}: take it off CIRCLE_EXCEPTIONS"


def test_the_circle_check_finds_a_circle(tmp_path: Path) -> None:
    pkg = tmp_path / "pkg"
    pkg.mkdir()
    (pkg / "__init__.py").write_text("")
    (pkg / "a.py").write_text("from .b import x\n")
    (pkg / "b.py").write_text("from typing import TYPE_CHECKING\nif TYPE_CHECKING:\n    from .c import y\nx = 1\n")
    (pkg / "c.py").write_text("from . import a\n\ndef f():\n    from . import b\n")
    files = list(pkg.rglob("*.py"))

    def name(f: Path) -> str:
        parts = list(f.relative_to(tmp_path).with_suffix("").parts)
        return ".".join(parts[:-1] if parts[-1] == "__init__" else parts)

    global PKG
    saved, PKG = PKG, tmp_path / "pkg"  # _module_name reads names relative to PKG's parent
    try:
        modules = {name(f) for f in files}
        graph = {name(f): _module_level_imports(f, modules) for f in files}
    finally:
        PKG = saved
    assert graph == {"pkg": set(), "pkg.a": {"pkg.b"}, "pkg.b": set(), "pkg.c": {"pkg.a"}}
    assert _circles(graph) == []
    graph["pkg.b"].add("pkg.c")  # b importing c at module level closes a -> b -> c -> a
    assert _circles(graph) == [["pkg.a", "pkg.b", "pkg.c"]]


# -- no import circle anywhere, counting every import ---------------------------------------------


def _all_imports(path: Path, modules: set[str]) -> set[str]:
    """Modules of `modules` that `path` names in any import statement: at module level, under
    TYPE_CHECKING, inside functions (farm-studio's count: a circle typing hides is still a circle).
    `from package import name` counts for the submodule when `name` is one, else for the package;
    `import a.b.c` for the longest prefix that is a module of ours."""
    tree = ast.parse(path.read_text(encoding="utf-8"))
    here = _module_name(path).split(".")
    package = here if path.name == "__init__.py" else here[:-1]
    out: set[str] = set()

    def ours(name: str) -> str | None:
        while name and name not in modules:
            name = name.rpartition(".")[0]
        return name or None

    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            out.update(m for a in node.names if (m := ours(a.name)))
        elif isinstance(node, ast.ImportFrom):
            base = package[: len(package) - node.level + 1] if node.level else []
            mod = ".".join([*base, *(node.module.split(".") if node.module else [])])
            for a in node.names:
                target = f"{mod}.{a.name}" if f"{mod}.{a.name}" in modules else ours(mod)
                if target:
                    out.add(target)
    out.discard(_module_name(path))
    return out


def _import_graph(root: Path) -> dict[str, set[str]]:
    files = [*root.rglob("*.py"), *root.rglob("*.pyi")]  # a stub-only module (catalog_types.pyi) too
    modules = {_module_name(f) for f in files}
    return {_module_name(f): _all_imports(f, modules) for f in files}


# Imports another branch removes (issue 28's work shared between helpers): client/feeds.py's
# TYPE_CHECKING import of the core gives way to a narrow Protocol on the geotag branch. Delete the
# entry once that is merged; nothing else may be added here.
BEING_REMOVED: set[tuple[str, str]] = set()  # edges a branch in flight removes (none now)


def test_no_import_circle_anywhere_in_src() -> None:
    """Issue 28: not one strongly connected component in the whole package's import graph, with
    TYPE_CHECKING and function-level imports counted (a helper that holds the whole client core
    back through a TYPE_CHECKING import is a circle too: give it a narrow Protocol instead)."""
    graph = _import_graph(PKG)
    for importer, imported in BEING_REMOVED:
        graph.get(importer, set()).discard(imported)
    circles = _circles(graph)
    assert not circles, "\n".join(" <-> ".join(c) for c in circles)


def test_the_full_count_sees_hidden_imports(tmp_path: Path) -> None:
    pkg = tmp_path / "pkg"
    pkg.mkdir()
    (pkg / "__init__.py").write_text("")
    (pkg / "a.py").write_text("from .b import x\n")
    (pkg / "b.py").write_text("from typing import TYPE_CHECKING\nif TYPE_CHECKING:\n    from .c import y\nx = 1\n")
    (pkg / "c.py").write_text("def f():\n    import pkg.a.nothing\n")
    global PKG
    saved, PKG = PKG, pkg  # _module_name reads names relative to PKG's parent
    try:
        graph = _import_graph(pkg)
    finally:
        PKG = saved
    assert graph == {"pkg": set(), "pkg.a": {"pkg.b"}, "pkg.b": {"pkg.c"}, "pkg.c": {"pkg.a"}}
    assert _circles(graph) == [["pkg.a", "pkg.b", "pkg.c"]]


def test_cli_help_imports_no_command_module() -> None:
    """`topgimbal --help` and the dispatch to a command load neither the protocol core nor asyncio
    nor any command module (cli/main.py, the command index); `decode` loads its own module only, and
    of the protocol core what decoding a frame given whole needs."""
    import subprocess

    code = (
        "import contextlib, io, sys\n"
        "from topgimbal.cli.main import parse\n"
        "with contextlib.suppress(SystemExit), contextlib.redirect_stdout(io.StringIO()):\n"
        "    parse(sys.argv[1:])\n"
        "print(' '.join(sorted(m for m in sys.modules if m.startswith(('topgimbal', 'asyncio')))))\n"
    )
    run = [sys.executable, "-c", code]
    loaded = subprocess.run([*run, "--help"], capture_output=True, text=True, check=True, timeout=120).stdout.split()
    assert "topgimbal.cli.main" in loaded, loaded
    assert not [m for m in loaded if m.startswith(("topgimbal.protocol", "asyncio", "topgimbal.cli.device"))], loaded
    loaded = subprocess.run(
        [*run, "decode", "X"], capture_output=True, text=True, check=True, timeout=120
    ).stdout.split()
    assert "topgimbal.cli.protocol_cmds" in loaded, loaded
    assert not [m for m in loaded if m.startswith(("asyncio", "topgimbal.sim", "topgimbal.client"))], loaded
    assert not {"topgimbal.cli.device_cmds", "topgimbal.cli.console_cmd"} & set(loaded), loaded
    # nor the capture tools (decode --pcap imports them when it runs) nor the streaming parser
    assert not {"topgimbal.cli.wire_cmds", "topgimbal.protocol.parser"} & set(loaded), loaded


def test_lazy_packages_still_give_their_names_and_submodules() -> None:
    """The PEP 562 `__getattr__`s (topgimbal, client, sim, sim.servers) load a name on first use,
    a submodule too (as the eager imports made it an attribute), and refuse anything else."""
    import subprocess

    code = (
        "import topgimbal, topgimbal.client as c, topgimbal.sim as s, topgimbal.sim.servers as v\n"
        "assert topgimbal.Frame.__name__ == 'Frame' and topgimbal.Gimbal.__name__ == 'Gimbal'\n"
        "assert topgimbal.protocol.Frame is topgimbal.Frame and c.engine.Engine is c.Engine\n"
        "assert s.Simulator.__name__ == 'Simulator' and v.UdpServer.__name__ == 'UdpServer'\n"
        "for mod in (topgimbal, c, s, v):\n"
        "    try:\n"
        "        mod.no_such_name\n"
        "    except AttributeError:\n"
        "        pass\n"
        "    else:\n"
        "        raise SystemExit(f'{mod.__name__}.no_such_name did not raise')\n"
        "print('ok')\n"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120, check=False)
    assert out.stdout.strip() == "ok", out.stderr


# -- one clock ---------------------------------------------------------------------------------------

# Reading a clock directly: the monotonic and wall clocks of `time`, an event loop's `time()`, and
# `datetime`'s now. Everything else calls `topgimbal.clock` (monotonic(), wall_time()) or takes an
# injected `clock`, so a fake clock or a virtual-time loop moves every deadline at once.
CLOCK_CALLS = {
    "time": {"monotonic", "monotonic_ns", "time", "time_ns", "perf_counter", "perf_counter_ns"},
    "datetime": {"now", "utcnow", "today"},
    "date": {"today"},
}

# Where a direct clock read is allowed, and which: the clock module itself, and wall-time dates
# where the clock module cannot be used (the protocol core imports only the standard library).
CLOCKLESS_ARGS = {"strftime": 1, "localtime": 0, "gmtime": 0, "ctime": 0, "asctime": 0}  # args without a time
CLOCK_ALLOWED: dict[str, set[str]] = {
    "clock.py": {"*"},
    "protocol/fields/time.py": {"datetime.now"},  # `--time now`: the operator's local date, sent once
}


def _clock_reads(path: Path) -> list[tuple[int, str]]:
    """(line, what) for each direct clock read in a file: `time.monotonic()` and the like (also
    passed uncalled as a clock), `from time import monotonic`, and `<...loop>.time` (also
    `get_running_loop().time`)."""
    tree = ast.parse(path.read_text(encoding="utf-8"))
    out = []
    for node in ast.walk(tree):
        # time's formatters read the clock themselves when given no time: time.strftime(FMT),
        # time.localtime(), time.gmtime(), time.ctime(), time.asctime()
        if (
            isinstance(node, ast.Call)
            and isinstance(node.func, ast.Attribute)
            and isinstance(node.func.value, ast.Name)
            and node.func.value.id == "time"
            and len(node.args) == CLOCKLESS_ARGS.get(node.func.attr, -1)
        ):
            out.append((node.lineno, f"time.{node.func.attr}"))
        if isinstance(node, ast.ImportFrom) and node.module in CLOCK_CALLS and not node.level:
            out += [(node.lineno, f"{node.module}.{a.name}") for a in node.names if a.name in CLOCK_CALLS[node.module]]
        if not isinstance(node, ast.Attribute):
            continue
        owner = node.value
        if isinstance(owner, ast.Attribute) and owner.attr in CLOCK_CALLS:  # datetime.datetime.now
            name = owner.attr
        elif isinstance(owner, ast.Name):
            name = owner.id
        else:
            name = ""
        if name in CLOCK_CALLS and node.attr in CLOCK_CALLS[name]:
            out.append((node.lineno, f"{name}.{node.attr}"))
            continue
        loopish = (isinstance(owner, ast.Name) and owner.id.lstrip("_").endswith("loop")) or (
            isinstance(owner, ast.Attribute) and owner.attr.lstrip("_").endswith("loop")
        )
        loop_call = (
            isinstance(owner, ast.Call)
            and isinstance(owner.func, ast.Attribute)
            and owner.func.attr in ("get_running_loop", "get_event_loop")
        )
        if node.attr == "time" and (loopish or loop_call):
            out.append((node.lineno, "loop.time"))
    return out


def test_clocks_are_read_only_through_topgimbal_clock() -> None:
    bad = []
    for path in sorted(PKG.rglob("*.py")):
        rel = path.relative_to(PKG).as_posix()
        allowed = CLOCK_ALLOWED.get(rel, set())
        for line, what in _clock_reads(path):
            if "*" not in allowed and what not in allowed:
                bad.append(f"{rel}:{line}: {what} (use topgimbal.clock.monotonic/wall_time or an injected clock)")
    assert not bad, "\n".join(bad)


def test_the_clock_rule_finds_direct_reads(tmp_path: Path) -> None:
    src = tmp_path / "m.py"
    src.write_text(
        "import asyncio, time, datetime\nfrom time import perf_counter\n"
        "a = time.monotonic()\nb = time.time\nc = asyncio.get_running_loop().time()\n"
        "def f(loop):\n    return loop.time() + self._loop.time()\n"
        "d = datetime.datetime.now()\ne = time.sleep(0)\n"
        "f = time.strftime('%Y') + time.strftime('%Y', time.gmtime(0))\ng = time.localtime()\n"
    )
    found = sorted(_clock_reads(src))
    assert found == [
        (2, "time.perf_counter"), (3, "time.monotonic"), (4, "time.time"), (5, "loop.time"),
        (7, "loop.time"), (7, "loop.time"), (8, "datetime.now"), (10, "time.strftime"), (11, "time.localtime"),
    ], found  # fmt: skip
    assert CLOCK_ALLOWED.keys() <= {p.relative_to(PKG).as_posix() for p in PKG.rglob("*.py")}


# -- waiting with a time limit: topgimbal.timeouts.within, never asyncio.wait_for -------------------


def _wait_for_calls(path: Path) -> list[int]:
    """Lines that use `asyncio.wait_for` (called or imported): before CPython 3.12 it can swallow
    a cancellation (topgimbal/timeouts.py says how that hung a bridge's close)."""
    tree = ast.parse(path.read_text(encoding="utf-8"))
    lines = []
    for node in ast.walk(tree):
        name = node.value.id if isinstance(node, ast.Attribute) and isinstance(node.value, ast.Name) else ""
        if isinstance(node, ast.Attribute) and node.attr == "wait_for" and name == "asyncio":
            lines.append(node.lineno)
        if isinstance(node, ast.ImportFrom) and node.module == "asyncio":
            lines += [node.lineno for a in node.names if a.name == "wait_for"]
    return lines


def test_no_asyncio_wait_for_in_the_package() -> None:
    bad = [f"{p.relative_to(PKG).as_posix()}:{line}" for p in sorted(PKG.rglob("*.py")) for line in _wait_for_calls(p)]
    assert not bad, "use topgimbal.timeouts.within (asyncio.wait_for can lose a cancellation): " + ", ".join(bad)


def test_the_wait_for_rule_finds_it(tmp_path: Path) -> None:
    src = tmp_path / "m.py"
    src.write_text("import asyncio\nfrom asyncio import wait_for\nx = asyncio.wait_for(f(), 1)\ncond.wait_for(p)\n")
    assert _wait_for_calls(src) == [2, 3]


# -- one earth model and one angle wrap: topgimbal.geo ---------------------------------------------

# Earth constants (WGS84's semi-axes and flattening, the mean and the authalic radii) and `% 360`
# angle arithmetic belong to topgimbal/geo (earth.py: wrap180 / wrap360, the ellipsoid); elsewhere a
# copy drifts (six wraps, thirteen inline ones and three radii once did).
EARTH_CONSTANTS = (6378137.0, 6356752.314245, 6371000.0, 6371008.8, 6371008.7714, 6371007.2, 298.257223563, 298.257)


def _geo_rule_breaks(path: Path) -> list[tuple[int, str]]:
    """(line, what) for `x % 360` (also `math.fmod(x, 360)` and `%=`) and earth constants."""
    tree = ast.parse(path.read_text(encoding="utf-8"))
    out = []

    def is_360(node: ast.AST) -> bool:
        return isinstance(node, ast.Constant) and type(node.value) in (int, float) and node.value in (360, 360.0)

    for node in ast.walk(tree):
        if (
            isinstance(node, (ast.BinOp, ast.AugAssign))
            and isinstance(node.op, ast.Mod)
            and is_360(node.right if isinstance(node, ast.BinOp) else node.value)
        ):
            out.append((node.lineno, "% 360"))
        elif (
            isinstance(node, ast.Call)
            and isinstance(node.func, ast.Attribute)
            and node.func.attr == "fmod"
            and len(node.args) == 2
            and is_360(node.args[1])
        ):
            out.append((node.lineno, "fmod 360"))
        elif (
            isinstance(node, ast.Constant)
            and type(node.value) in (int, float)
            and any(abs(node.value - c) < 1e-3 for c in EARTH_CONSTANTS)
        ):
            out.append((node.lineno, f"earth constant {node.value}"))
    return out


def test_angle_wraps_and_earth_constants_live_in_geo() -> None:
    bad = [
        f"{p.relative_to(PKG).as_posix()}:{line}: {what} (use topgimbal.geo.earth)"
        for p in sorted(PKG.rglob("*.py"))
        if p.relative_to(PKG).parts[0] != "geo"
        for line, what in _geo_rule_breaks(p)
    ]
    assert not bad, "\n".join(bad)


def test_the_geo_rule_finds_wraps_and_constants(tmp_path: Path) -> None:
    src = tmp_path / "m.py"
    src.write_text(
        "import math\na = (b + 180.0) % 360.0 - 180.0\nc = d % 360\ne = 6371008.8\nf = 6378137\n"
        "g = math.fmod(h, 360)\ni = j % 36\nk = '%d' % 360\nx %= 360\ny = 1 / 298.257223563\n"
    )
    assert sorted(_geo_rule_breaks(src)) == [
        (2, "% 360"), (3, "% 360"), (4, "earth constant 6371008.8"), (5, "earth constant 6378137"),
        (6, "fmod 360"), (8, "% 360"), (9, "% 360"), (10, "earth constant 298.257223563"),
    ], sorted(_geo_rule_breaks(src))  # fmt: skip
