# lomanip: `make demo` runs the main job, `make test` runs the tests. Both set up first.
SHELL := /bin/bash
VENV := .venv
PY := $(VENV)/bin/python
# Keep DDS on this machine unless the user explicitly asks for more.
export ROS_AUTOMATIC_DISCOVERY_RANGE ?= LOCALHOST
export MUJOCO_GL ?= egl
export PYTHONUNBUFFERED := 1

.PHONY: setup demo test test-all bench bench-graph bench-perception bench-plan bench-to bench-exec bench-push clean help

help:
	@echo "make setup   - idempotent set-up: apt packages (as root), .venv, interfaces, lomanip packages"
	@echo "make demo    - run the main job (see README)"
	@echo "make test    - run the test suite (unit + graph tests; heavy cases are in the benchmarks)"
	@echo "make bench   - run every benchmark below and print their figures (long)"
	@echo "make bench-graph | bench-perception | bench-plan | bench-to | bench-exec | bench-push - one benchmark (see README)"

setup:
	@tools/setup.sh

demo: setup
	$(VENV)/bin/lomanip demo

test: setup
	$(PY) -m pytest -q tests

test-all: setup
	$(PY) -m pytest -q -m "slow or not slow" tests

bench: bench-graph bench-perception bench-plan bench-to bench-exec bench-push

bench-graph: setup
	$(PY) tools/bench_graph.py

bench-perception: setup
	$(PY) tools/bench_perception.py --docs-figure docs/img/contact_transfer.png

bench-plan: setup
	$(PY) tools/bench_plan.py

bench-to: setup
	$(PY) tools/bench_to.py

bench-exec: setup
	$(PY) tools/bench_exec.py

bench-push: setup
	$(PY) tools/bench_push.py --cases all
	$(PY) tools/bench_push.py --cases all --perturb all

clean:
	rm -rf build runs .pytest_cache
