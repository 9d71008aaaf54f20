# topgimbal: everything a fresh machine needs goes through these targets.
PY ?= python3
VENV := .venv
BIN := $(VENV)/bin
STAMP := $(VENV)/.installed

.PHONY: test demo lint typecheck pytest docs docs-check bench clean browser-deps video-deps

$(STAMP): pyproject.toml
	$(PY) -m venv $(VENV)
	$(BIN)/pip install --quiet --upgrade pip
	$(BIN)/pip install --quiet -e '.[dev]'
	touch $(STAMP)

# Debian's chromium for the browser tests (browser downloads do not work here).
browser-deps:
	@if [ ! -x /usr/bin/chromium ]; then \
	  echo "installing Debian's chromium"; \
	  if [ "$$(id -u)" = 0 ]; then SUDO=; else SUDO=sudo; fi; \
	  $$SUDO apt-get update -qq && $$SUDO env DEBIAN_FRONTEND=noninteractive apt-get install -y -qq chromium >/dev/null; \
	fi

# Debian's ffmpeg/ffprobe: the video tests read the simulator's RTSP streams with them.
video-deps:
	@if ! command -v ffprobe >/dev/null || ! command -v ffmpeg >/dev/null; then \
	  echo "installing Debian's ffmpeg"; \
	  if [ "$$(id -u)" = 0 ]; then SUDO=; else SUDO=sudo; fi; \
	  $$SUDO apt-get update -qq && $$SUDO env DEBIAN_FRONTEND=noninteractive apt-get install -y -qq ffmpeg >/dev/null; \
	fi

lint: $(STAMP)
	$(BIN)/ruff check src tests bench
	$(BIN)/ruff format --check src tests bench

typecheck: $(STAMP)
	$(BIN)/mypy

docs: $(STAMP)
	$(BIN)/python -m topgimbal.tools.gendocs docs/protocol.md

docs-check: $(STAMP)
	$(BIN)/python -m topgimbal.tools.gendocs --check docs/protocol.md

pytest: $(STAMP) browser-deps video-deps
	$(BIN)/python -m pytest -q

test: $(STAMP) browser-deps video-deps lint typecheck pytest

demo: $(STAMP)
	$(BIN)/python -m topgimbal.tools.demo

bench: $(STAMP)
	$(BIN)/python bench/codec.py
	$(BIN)/python bench/sim.py
	$(BIN)/python bench/latency.py
	$(BIN)/python bench/video.py

clean:
	rm -rf $(VENV) .pytest_cache .mypy_cache .ruff_cache test-artifacts
