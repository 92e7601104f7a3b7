# One command sets up and regenerates (`make codegen`), one sets up and tests (`make test`).
PYTHON ?= python3
VENV   := .venv
PY     := $(VENV)/bin/python
STAMP  := $(VENV)/.installed

.PHONY: codegen test test-long test-busy bench sim-report fuzz fuzz-long mutate clean

$(STAMP): pyproject.toml
	$(PYTHON) -m venv --system-site-packages $(VENV)
	$(PY) -m pip install -q -e '.[test]'
	touch $@

codegen: $(STAMP)
	$(PY) -m uavarm.codegen

# Every core for the tests that only compute; then, also on every core, the ones that run a
# simulated board in real time beside the link client, the calibrations or the ROS node
# (meant not to depend on the load; `make test-busy` checks it). The second stage runs even
# if the first failed; both stages' results are shown, and either failing fails the target.
test: $(STAMP)
	@$(PY) -m pytest -q -n auto --dist worksteal -m "not realtime and not long"; computing=$$?; \
	$(PY) -m pytest -q -n auto --dist worksteal -m realtime; realtime=$$?; \
	verdict() { [ $$1 -eq 0 ] && echo passed || echo "FAILED (pytest exit $$1)"; }; \
	echo "make test: computing stage $$(verdict $$computing); real-time stage $$(verdict $$realtime)"; \
	[ $$computing -eq 0 ] && [ $$realtime -eq 0 ]

# The denser runs and the other cases of checks make test makes on their worst case: the
# safety grid's slowest servos on a 24 mm grid of targets and the model file's lag on the
# 48 mm grid, three edge set positions under rocking on the quickest servos.
test-long: $(STAMP)
	$(PY) -m pytest -q -n auto -m long

# The real-time stage (SITL, link, calibrations, ROS) and the fuzz tests with two busy
# processes beside them (CPU-bound loops at normal priority, stopped at the end): what makes
# their verdicts, simulated time and counts of inputs, must not depend on the machine's load.
test-busy: $(STAMP)
	@$(PY) -c "while True: pass" & busy1=$$!; $(PY) -c "while True: pass" & busy2=$$!; \
	trap 'kill $$busy1 $$busy2' EXIT; \
	$(PY) -m pytest -q -n auto --dist worksteal -m realtime; realtime=$$?; \
	$(PY) -m pytest -q tests/test_fuzz.py; fuzz=$$?; \
	verdict() { [ $$1 -eq 0 ] && echo passed || echo "FAILED (pytest exit $$1)"; }; \
	echo "make test-busy (two busy processes beside): real-time stage $$(verdict $$realtime); fuzz $$(verdict $$fuzz)"; \
	[ $$realtime -eq 0 ] && [ $$fuzz -eq 0 ]

bench: $(STAMP)
	$(PY) bench/run.py

# The closed-loop simulator's full table (docs/simulator.md): bench, hover and
# manoeuvre x the quaternion (IMU only), link, imu-velocity and link-velocity estimators x
# 16 seeds x 30 s, each seed drawing its errors across the ranges of uavarm/sim/error_ranges.py,
# stated as the median, 95th percentile and worst across the seeds, into
# build/sim-report/report.md with plots. Stops with the key's name if a preset's model keys
# are unknown to this firmware.
sim-report: $(STAMP)
	$(PY) -m uavarm.sim.report --out build/sim-report

# Fuzz harnesses (fuzz/, docs/fuzzing.md; needs clang libclang-rt-14-dev and atheris).
fuzz: $(STAMP)
	$(PY) fuzz/run.py --time 20 --jobs 2

# The long run of docs/fuzzing.md's figures: 10 million inputs of each harness; the whole
# application (both servo families) and the model loader on both cores, 5 million each
# (about four hours in all on an idle 2-core machine).
fuzz-long: $(STAMP)
	$(PY) fuzz/run.py --runs 10000000 llcp_rx dxl_parser dxl2_parser
	$(PY) fuzz/run.py --runs 5000000 --workers 2 app_link
	$(PY) fuzz/run.py --runs 5000000 --workers 2 app_link_x
	$(PY) fuzz/run.py --runs 5000000 --workers 2 model_loader

# Mutation testing (README "Verification"): mutants of the safety-relevant firmware, templates
# and model modules against their behavioural tests; a benchmark, not part of `make test`.
# Resumes from build/mutate/results.jsonl. E.g. make mutate MUTATE_ARGS="--jobs 2 --target llcp"
MUTATE_ARGS ?= --jobs 1
mutate: $(STAMP)
	$(PY) -m mutation $(MUTATE_ARGS)

clean:
	rm -rf build
