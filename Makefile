# The two commands: `make demo` and `make test` (`make demo DEMO_ARGS=--dynamic`: the dynamic
# scene; `--motion`: motions checked between frames; `--camera`: a depth camera's clouds, a
# person no scene file holds; DEMO_ARGS go to collision_sensor_demo).
# Each creates .venv when it is missing and installs the package with its `ros` and `test`
# extras (editable, so tests run this tree); the stamp makes a second run reinstall nothing
# until setup.py, setup.cfg, package.xml or the engine's C++ sources (cpp/, compiled into the
# extension at install) change.
PYTHON ?= python3
VENV := .venv
BIN := $(VENV)/bin
STAMP := $(VENV)/.collision_sensor-installed

# DDS stays on this machine: shared memory only, and a domain of its own unless one is given.
export FASTDDS_BUILTIN_TRANSPORTS ?= SHM
export ROS_DOMAIN_ID ?= 42

.PHONY: demo test bench clean

$(STAMP): setup.py setup.cfg package.xml pyproject.toml $(wildcard cpp/*.cpp cpp/*.hpp)
	test -x $(BIN)/python || $(PYTHON) -m venv $(VENV)
	$(BIN)/python -m pip install --quiet --upgrade pip wheel
	$(BIN)/python -m pip install --quiet -e '.[ros,test]'
	touch $(STAMP)

demo: $(STAMP)
	$(BIN)/collision_sensor_demo $(DEMO_ARGS)

test: $(STAMP)
	$(BIN)/python -m pytest test

# Every benchmark (benchmarks/, not installed), three runs each, into docs/performance.md:
# `make bench`; one section again: `make bench BENCH_ARGS="--only node"`; the scenarios alone,
# printed: `$(BIN)/python -m benchmarks --help`.
bench: $(STAMP)
	$(BIN)/python -m benchmarks page --runs 3 --output docs/performance.md $(BENCH_ARGS)

clean:
	rm -rf $(VENV) *.egg-info build
