# tlfleet — the two set-up commands are `make run` and `make test`; both create .venv if missing.
PYTHON ?= python3
VENV   ?= .venv
BIN    := $(VENV)/bin
PY     := $(BIN)/python

.PHONY: run test test-fast test-full bench lint clean compose-run system-deps

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

# The ROS 2 extra (rclpy and message wheels, mcap; about 30 s and 60 MB the first time): the
# hardware bridge's, the ROS mirror's and the MCAP export's tests run in `make test`.
$(VENV)/.installed-ros2: $(VENV)/.installed-test
	$(PY) -m pip install --quiet -e ".[test,ros2]"
	touch $@

run: $(VENV)/.installed
	$(BIN)/tlfleet run scenarios/scenario1.toml --lockstep

test: $(VENV)/.installed-test $(VENV)/.installed-ros2
	$(PY) -m pytest

# The inner loop: every unit, property and closed-loop test, no process-starting or system test
# (about 2 minutes on 2 cores).
test-fast: $(VENV)/.installed-test
	$(PY) -m pytest -m "not slow and not system and not needs_system"

# The whole suite with every Hypothesis property at its full budget (tests/hypothesis_budget.py).
test-full: $(VENV)/.installed-test $(VENV)/.installed-ros2
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

clean:
	rm -rf $(VENV) build *.egg-info bench/results
