# rodlab: the two commands of the quick start are `make run` and `make test`.
SHELL := /bin/bash
PYTHON ?= python3
VENV := .venv
PY := $(VENV)/bin/python
PIP := $(VENV)/bin/pip
STAMP := $(VENV)/.rodlab-installed
# torch is pinned in the same pip command as everything else (a local CPU build here; an
# unpinned torch would pull gigabytes of CUDA wheels).
PIP_SPECS := "torch==2.13.0" -e ".[dev,peers,sweep]"
SUDO := $(shell [ "$$(id -u)" = 0 ] || echo sudo)

.PHONY: run test install system-deps warmup lint clean

$(STAMP): pyproject.toml
	@$(PYTHON) -m venv $(VENV) 2>/dev/null || { \
	  echo "python3 -m venv failed: installing Debian's python3-venv"; \
	  $(SUDO) apt-get update && DEBIAN_FRONTEND=noninteractive $(SUDO) apt-get install -y python3-venv && \
	  $(PYTHON) -m venv $(VENV); }
	$(PIP) install --upgrade pip
	$(PIP) install $(PIP_SPECS)
	-$(VENV)/bin/rerun analytics disable >/dev/null 2>&1
	touch $(STAMP)

install: $(STAMP)

# System packages the tests need: Debian's Chromium for the browser tests (Playwright never downloads a browser)
# and a C++ compiler for the compiled-update tests (torch.compile's CPU back-end; `rodlab train --compile`).
system-deps:
	@if [ ! -x /usr/bin/chromium ]; then \
	  echo "installing Debian chromium for the browser tests"; \
	  $(SUDO) apt-get update && DEBIAN_FRONTEND=noninteractive $(SUDO) apt-get install -y chromium chromium-driver fonts-liberation; \
	fi
	@if ! command -v g++ >/dev/null && ! command -v c++ >/dev/null; then \
	  echo "installing g++ for torch.compile (the compiled-update tests)"; \
	  $(SUDO) apt-get update && DEBIAN_FRONTEND=noninteractive $(SUDO) apt-get install -y g++; \
	fi

# Compile (or load from cache) the numba kernels once, visibly.
warmup: install
	$(PY) -m sim.warmup

run: install warmup
	$(VENV)/bin/rodlab workbench

# The suite runs on TEST_WORKERS processes (pytest-xdist; which tests stay together on one process is said in
# tests/conftest.py, process_group); TEST_WORKERS=0 runs it in this process.
TEST_WORKERS ?= 2

test: install system-deps warmup
	$(PY) -m pytest $(if $(filter 0,$(TEST_WORKERS)),,-n $(TEST_WORKERS))

lint: install
	$(VENV)/bin/ruff check sim policies workbench benchmarks tests examples tools rodlab_cli.py

clean:
	rm -rf $(VENV) build *.egg-info .pytest_cache
	find . -name __pycache__ -type d -prune -exec rm -rf {} +
