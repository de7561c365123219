# One-command set-up: `make test` and `make demo` build everything they need.
# The virtual environment is made once and reused; it is rebuilt when
# requirements.txt or a package's setup.py changes.

PYTHON ?= $(shell command -v python3.11 || command -v python3)
VENV := .venv
BIN := $(VENV)/bin
PACKAGES := ft_core ft_msgs_py ft_controller ft_monitor ft_sim
SETUPS := $(foreach p,$(PACKAGES),ros_ws/src/$(p)/setup.py ros_ws/src/$(p)/setup.cfg)
STAMP := $(VENV)/.installed
WARM_UP := from ft_core import detection, engine, remap, robots, smoothing; engine.ResolutionEngine(robots.load('panda')); \
	engine.ResolutionEngine(robots.load('panda'), engine.EngineConfig(resolution='least_norm')); \
	detection.compile_ahead(); smoothing.compile_ahead(); remap.compile_ahead()

PYTEST := $(BIN)/python -m pytest
#: The ft_core sources whose compiled functions numba caches (see `build`).
NUMBA_STAMP := ros_ws/build/.ft_core-sources

.PHONY: all venv build lint test test-fast test-kernels demo bench clean

all: test

$(STAMP): requirements.txt pyproject.toml $(SETUPS)
	$(PYTHON) -m venv $(VENV)
	$(BIN)/python -m pip install --quiet -r requirements.txt
	$(BIN)/python -m pip install --quiet --no-deps --no-build-isolation \
		$(foreach p,$(PACKAGES),-e ros_ws/src/$(p))
	$(BIN)/python -m pip install --quiet --no-deps --no-build-isolation .
	touch $@

venv: $(STAMP)

# colcon install space with the layout `ros2 run` uses (ros_ws/install).
build: $(STAMP)
	cd ros_ws && ../$(BIN)/colcon --log-base log build --base-paths src \
		--build-base build --install-base install --event-handlers console_cohesion- summary+
	# numba's cache of a function is checked against that function's file only, not the
	# files of the functions it calls: when any ft_core source (subpackages included)
	# changed, drop every cached compilation, or the engine's cycle would keep an old
	# postfailure.
	@sources=$$(find ros_ws/src/ft_core/ft_core -name '*.py' | LC_ALL=C sort | xargs cat | sha256sum); \
	if [ "$$sources" != "$$(cat $(NUMBA_STAMP) 2>/dev/null)" ]; then \
		find ros_ws/src/ft_core ros_ws/install/ft_core -name '*.nb[ic]' -delete; \
		echo "$$sources" > $(NUMBA_STAMP); fi
	# Compile the engine's cycle, the detector and the smoother's test (numba, cached next to
	# each copy of the sources: the install space's and the editable one) now, not in the
	# first node to start.
	for path in ros_ws/install/ft_core/lib/python*/site-packages ""; do \
		PYTHONPATH=$$path $(BIN)/python -c "$(WARM_UP)" || exit 1; done

lint: $(STAMP)
	$(BIN)/ruff check .
	$(BIN)/mypy

# Every tier (markers in pyproject.toml, docs/testing.md), on both cores, the 15 slowest
# tests listed at the end.
test: build lint
	$(PYTEST) -n 2 --dist worksteal --durations=15

# The ROS-free unit tier alone: under a minute.
test-fast: $(STAMP)
	$(PYTEST) tests/unit -m unit -n 2 --dist worksteal --durations=15

# The unit tier again under other OpenBLAS kernels, whose rounding differs (CI runs it
# after `make test`): Prescott runs on every x86-64 CPU, Haswell needs AVX2.
test-kernels: $(STAMP)
	if [ "$$(uname -m)" = x86_64 ]; then \
		OPENBLAS_CORETYPE=Prescott $(PYTEST) tests/unit -m unit -n 2 -q && \
		if grep -qw avx2 /proc/cpuinfo; then OPENBLAS_CORETYPE=Haswell $(PYTEST) tests/unit -m unit -n 2 -q; \
		else echo "no AVX2 on this CPU: the Haswell kernel is not tried"; fi; \
	else echo "OpenBLAS kernels are named for x86-64: nothing to try on $$(uname -m)"; fi

demo: $(STAMP)
	$(BIN)/ft-demo

# Speed and detection-quality figures (not asserted in tests): writes bench_out/*.md and
# *.json; about three hours (the fault campaign on a realistic plant, 160 runs, and
# on the physics plant, 40; the fault grid in process and 60 faults deployed, idle and
# loaded; the command streams against the arm's limits; the deployed
# nodes' 30-minute soak on each plant, the nodes' 10-minute memory run, the two layouts at
# two rates). The soft-limits study with 200 runs per condition is docs/campaign.md's
# longer ft-campaign command.
bench: $(STAMP)
	$(BIN)/python bench/engine_cycle.py --out bench_out
	$(BIN)/python bench/engine_scaling.py --out bench_out
	$(BIN)/python bench/selfmotion_trace.py --out bench_out
	$(BIN)/python bench/detection.py --out bench_out
	$(BIN)/python bench/faults.py --out bench_out
	$(BIN)/python bench/faults_processes.py --out bench_out
	$(BIN)/python bench/faults_processes.py --loaded --out bench_out
	$(BIN)/python bench/soak.py --out bench_out
	$(BIN)/python bench/observability.py --out bench_out
	$(BIN)/python bench/recovery.py --out bench_out
	$(BIN)/python bench/announce.py --out bench_out
	rm -rf bench_out/runs  # the campaign resumes from kept runs: start afresh
	$(BIN)/ft-campaign --runs 20 --latency 0.02 --response-time 0.03 --hold-last-command \
		--out bench_out
	rm -rf bench_out/campaign_physics/runs
	$(BIN)/ft-campaign --runs 5 --plant physics --latency 0.02 --response-time 0.03 \
		--hold-last-command --out bench_out/campaign_physics
	$(BIN)/python bench/commands.py --out bench_out
	$(BIN)/python bench/zhao_li_circle.py --out bench_out
	$(BIN)/python bench/campaign_scaling.py --out bench_out
	$(BIN)/python bench/nodes.py --out bench_out
	$(BIN)/python bench/layouts.py --out bench_out

clean:
	rm -rf $(VENV) ros_ws/build ros_ws/install ros_ws/log
