# The two commands: `make demo` and `make test` (`make check`: the quick tier of the tests, for
# the edit loop; `make bench`: the benchmarks; `make demo DEMO_ARGS=--dynamic`: the dynamic
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

# Test workers (pytest-xdist): one per core; each runs whole test files, in a DDS domain of its
# own (test/conftest.py). JOBS=0 runs the tests in this process.
JOBS ?= auto
PYTEST := $(BIN)/python -m pytest test -n $(JOBS) --dist loadfile
# The edit loop's tier: every test but the slow sweeps, packaging, demos, Ray and the node as a
# process of its own (markers: setup.cfg).
QUICK := not (slow or packaging or demo or ray or node_process)

.PHONY: demo test check bench clean

$(STAMP): setup.py setup.cfg package.xml pyproject.toml $(wildcard cpp/*.cpp cpp/*.hpp cpp/*.h cpp/hop/*.cpp)
	test -x $(BIN)/python || $(PYTHON) -m venv $(VENV)
	$(BIN)/python -m pip install --quiet --upgrade pip wheel
	# ROS 2 first: its wheels put rcl's headers in the venv, which the node's compiled
	# joint-state hop is built against (setup.py; without them the node takes joint states
	# through rclpy).
	$(BIN)/python -m pip install --quiet 'ros-jazzy-rclpy[fastrtps]' ros-jazzy-common-interfaces
	$(BIN)/python -m pip install --quiet -e '.[ros,test]'
	touch $(STAMP)

demo: $(STAMP)
	$(BIN)/collision_sensor_demo $(DEMO_ARGS)

test: $(STAMP)
	$(PYTEST)

check: $(STAMP)
	$(PYTEST) -m "$(QUICK)"

# Every benchmark (benchmarks/, not installed), three runs each, into docs/performance.md:
# `make bench`; one section again: `make bench BENCH_ARGS="--only node"`; the scenarios alone,
# printed: `$(BIN)/python -m benchmarks --help`.
bench: $(STAMP)
	$(BIN)/python -m benchmarks page --runs 3 --output docs/performance.md $(BENCH_ARGS)

clean:
	rm -rf $(VENV) *.egg-info build
