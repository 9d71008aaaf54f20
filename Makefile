# topgimbal: everything a fresh machine needs goes through these targets.
PY ?= python3
VENV := .venv
BIN := $(VENV)/bin
STAMP := $(VENV)/.installed

.PHONY: deps debian-deps test test-tak check flake demo lint typecheck pytest pytest-virtual docs docs-check bench clean browser-deps c-deps c-test tshark-deps video-deps gstreamer-deps exiftool-deps mavproxy-deps misb-deps

# The C fast path is compiled by `pip install`: rebuild it when its sources change.
$(STAMP): pyproject.toml setup.py src/topgimbal/_speedups/_ctop.c $(wildcard c/src/*.c c/include/*.h c/generated/*)
	$(PY) -m venv $(VENV)
	$(BIN)/pip install --quiet --upgrade pip
	$(BIN)/pip install --quiet -e '.[dev]'
	# MAVProxy for the ground-station tests, without its GUI stack (wx, matplotlib, vtk): its camera
	# module and a headless start need only what the dev extra has (defusedxml, OpenCV headless)
	$(BIN)/pip install --quiet --no-deps MAVProxy==1.8.75
	touch $(STAMP)

# Every Debian package below in one apt-get run (one index update, one dpkg run): `make test` asks
# for them all first, so on a fresh machine the per-group targets then find nothing missing.
debian-deps:
	@sh scripts/debian-deps

# Debian's chromium for the browser tests (browser downloads do not work here), and a CJK font
# so the vendors' Chinese terms never render as boxes. Installs only what is missing.
browser-deps:
	@sh scripts/debian-deps browser

# Debian's tshark (+ editcap, text2pcap from wireshark-common) for the Wireshark dissector tests.
# The preseed answers the "non-root users may capture" question (no: nothing here captures live).
tshark-deps:
	@sh scripts/debian-deps tshark

# Debian's ffmpeg/ffprobe: the video tests read the simulator's RTSP streams with them.
video-deps:
	@sh scripts/debian-deps video

# Debian's GStreamer: the RTP push tests play the stream with QGroundControl's pipeline
# (udpsrc ! rtpjitterbuffer ! rtph264depay ! avdec_h264; the decoder is in gstreamer1.0-libav).
gstreamer-deps:
	@sh scripts/debian-deps gstreamer

# Debian's exiftool: the media and geotag tests read the photos' EXIF / XMP with it.
exiftool-deps:
	@sh scripts/debian-deps exiftool

lint: $(STAMP)
	$(BIN)/ruff check src tests bench
	$(BIN)/ruff format --check src tests bench

typecheck: $(STAMP)
	$(BIN)/mypy

# Every file made from the catalog (docs/protocol.md, the Lua dissector, c/generated/, the CLI's
# command index, ...): one command, its REGISTRY in src/topgimbal/tools/regen.py.
docs: $(STAMP)
	$(BIN)/python -m topgimbal.tools.regen

docs-check: $(STAMP)
	$(BIN)/python -m topgimbal.tools.regen --check

# The suite in parallel (pytest-xdist): its loopback and external tiers mostly wait (sockets,
# timers, child processes), so more workers than cores pay on a 2-core machine (README, Development:
# the figures). --dist loadfile keeps a module on one worker: module-scoped fixtures (a console, a
# browser) start once. Tests marked `serial` share something process-wide and run alone afterwards.
PYTEST_WORKERS ?= 6
XDIST := -n $(PYTEST_WORKERS) --dist loadfile --max-worker-restart 0  # a crashed worker ends the run (a replaced one once hung it)

# The whole suite on the C fast path, then what the pure Python path has to prove again (what runs
# where no compiler built the extension): the protocol core, the fast path compared with it, and a
# few end-to-end client tests (every model through the engine).
PURE_TESTS := tests/protocol tests/speedups tests/client/test_engine.py tests/client/test_every_model_e2e.py

pytest: debian-deps $(STAMP) browser-deps tshark-deps video-deps gstreamer-deps exiftool-deps mavproxy-deps misb-deps
	$(BIN)/python -m pytest -q $(XDIST) -m "not serial and not service"
	if grep -rqE "mark\.serial|pytest\.mark\.serial" tests; then $(BIN)/python -m pytest -q -m "serial and not service"; fi
	TOPGIMBAL_PURE=1 $(BIN)/python -m pytest -q $(XDIST) -m "not serial" $(PURE_TESTS)

# The virtual tier (tests/conftest.py): memory transport and fake clocks, no socket, no process.
pytest-virtual: $(STAMP)
	$(BIN)/python -m pytest -q -n 2 --dist loadfile -m virtual

# CoT stored by a real OpenTAKServer (tests/mavlink/test_cot_tak_server.py): it needs PostgreSQL,
# RabbitMQ and Python >= 3.12, about 6 minutes to install, so `make test` does not select it (it is
# deselected, not skipped). Bring one up with scripts/opentakserver-loopback start, set the variables
# it prints, then run this: without them the test fails and says which are missing.
test-tak: $(STAMP)
	$(BIN)/python -m pytest -q -m service

# The flake harness: the loopback and external tiers RUNS times as `make test` runs them, beside HOG
# busy loops (a noisy neighbour), then a table of failures per test and each run's wall time and load
# (scripts/flake.py; README, Development).
RUNS ?= 3
HOG ?= 0
flake: $(STAMP) misb-deps
	$(BIN)/python scripts/flake.py --runs $(RUNS) --hog $(HOG) --workers $(PYTEST_WORKERS)

# libtopgimbal (c/): clang with libFuzzer and sanitizer runtimes, installed only when missing.
# MAVProxy as a MAVLink router in the tests (tests/mavlink/test_multi_router.py). --no-deps: its
# declared dependencies pull in opencv, vtk and matplotlib, which routing never imports.
mavproxy-deps: $(STAMP)
	@$(BIN)/python -c "import MAVProxy" 2>/dev/null || $(BIN)/pip install --quiet --no-deps MAVProxy==1.8.75

# pymisb, an independent MISB ST 0601 reader (tests/mavlink/test_klv_pymisb.py), needs Python >= 3.12:
# its own venv, from the first such interpreter found (python3.13, python3.12, pyenv's versions).
MISB_VENV := .venv-misb
MISB_STAMP := $(MISB_VENV)/.installed
misb-deps: $(MISB_STAMP)

$(MISB_STAMP):
	@py=""; for c in python3.13 python3.12 $$(ls -d $$HOME/.pyenv/versions/3.1[2-9]*/bin/python 2>/dev/null); do \
	  if command -v $$c >/dev/null 2>&1 && $$c -c 'import sys; sys.exit(sys.version_info < (3, 12))' 2>/dev/null; then py=$$c; break; fi; \
	done; \
	test -n "$$py" || { echo "misb-deps: no Python >= 3.12 found (python3.12 or pyenv install 3.12)" >&2; exit 1; }; \
	$$py -m venv $(MISB_VENV) && $(MISB_VENV)/bin/pip install --quiet 'pymisb==2.0.2' 'pymap3d>=3.1' 'numpy>=1.24'
	touch $(MISB_STAMP)

c-deps:
	@sh scripts/debian-deps c

# Warnings (gcc, clang), libc symbols, vectors under ASan/UBSan, libFuzzer and differential fuzzing
# for a bounded time (FUZZ_SECONDS, DIFF_SECONDS; 10 s each by default).
c-test: $(STAMP) c-deps
	$(MAKE) -C c test PYTHON=$(CURDIR)/$(BIN)/python

# The developer's loop: lint, types, regenerated files, and the virtual tier (no installs of Debian
# packages, no real waiting).
check: lint typecheck docs-check pytest-virtual

# The two installs overlap: apt downloads and unpacks while pip downloads and builds (measured one at
# a time on fresh systems: the Debian packages 132 s, the virtualenv without pip's cache 130 s).
deps:
	$(MAKE) --no-print-directory -j2 debian-deps $(STAMP)

test: deps $(STAMP) browser-deps tshark-deps video-deps gstreamer-deps exiftool-deps mavproxy-deps misb-deps c-deps lint typecheck docs-check pytest c-test

demo: $(STAMP)
	$(BIN)/python -m topgimbal.tools.demo

bench: $(STAMP)
	$(BIN)/python bench/codec.py
	$(BIN)/python bench/sim.py
	$(BIN)/python bench/latency.py
	$(BIN)/python bench/mavlink.py
	$(BIN)/python bench/console.py
	$(BIN)/python bench/proxy.py
	$(BIN)/python bench/faults.py
	$(BIN)/python bench/video.py
	$(BIN)/python bench/cli_start.py

clean:
	rm -rf $(VENV) .pytest_cache .mypy_cache .ruff_cache test-artifacts
