# One entry point for people and CI. `make demo` and `make test` set up .venv themselves.
PYTHON ?= python3.11
VENV := .venv
BIN := $(VENV)/bin
STAMP := $(VENV)/.installed

.PHONY: setup demo test test-floors colcon-test lint config fuzz bench bench-smoke bench-paper bench-paper-quick bench-partial bench-node bench-big-map bench-big-map-node bench-bag bench-cluster bench-trust clean

$(STAMP): setup.py setup.cfg package.xml
	$(PYTHON) -m venv $(VENV)
	$(BIN)/pip install --quiet --upgrade pip
	$(BIN)/pip install --quiet -e '.[ros,test,bench,lint]'
	touch $(STAMP)

setup: $(STAMP)

demo: $(STAMP)
	$(BIN)/frisicp-demo

# The README's test command: every test, in two runs. The computing ones (test/core, test/stream,
# test/bench) and those that run the command line on files and bags with minute-long timeouts
# (test/cli; the bag mode's command, batches, damaged and malformed bags, locating) TEST_JOBS at
# a time (pytest-xdist, a test file per worker: its module fixtures are built once); the rest,
# which send signals, run clusters or ROS and time their waits for an otherwise idle machine,
# one at a time (a new test folder lands here). pytest exits 5 when it collects nothing: that is
# a failure here, said plainly.
PARALLEL_TESTS := test/core test/stream test/bench test/cli test/bag/test_bag_command.py \
  test/bag/test_bag_batch.py test/bag/test_damaged_bags.py test/bag/test_bag_integrity.py test/bag/test_locate.py
TEST_JOBS ?= 2
test: $(STAMP)
	@$(BIN)/python -m pytest -q -n $(TEST_JOBS) --dist loadfile $(PARALLEL_TESTS); first=$$?; \
	  $(BIN)/python -m pytest -q test $(addprefix --ignore=,$(PARALLEL_TESTS)); second=$$?; \
	  for rc in $$first $$second; do if [ $$rc -eq 5 ]; then echo "pytest collected no tests: failing"; fi; done; \
	  if [ $$first -ne 0 ]; then exit $$first; fi; exit $$second

# The package in a plain ROS 2 workspace whose Python packages come only from package.xml's keys
# (test/support/workspace.py): colcon build, colcon test --packages-select frisicp_ros, colcon
# test-result. COLCON_TESTS chooses the tests: by default all but the clean-venv test (marked slow,
# it builds yet another venv from PyPI); COLCON_TESTS= runs them all.
COLCON_TESTS ?= -m "not slow"
colcon-test: $(STAMP)
	cd test && ../$(BIN)/python -m support.workspace $(COLCON_TESTS)

# setup.py's lower bounds, installed exactly (.ci/dependency_floors.py) in a venv of their own, run
# the bag tests: the code that leans most on other packages' APIs (rosbags, mcap); not the
# signal tests, which exercise the process's signal handling, not those APIs. ~2 min.
FLOORS := .venv-floors
test-floors:
	rm -rf $(FLOORS)
	$(PYTHON) -m venv $(FLOORS)
	$(FLOORS)/bin/pip install --quiet --upgrade pip
	$(FLOORS)/bin/pip install --quiet $$($(PYTHON) .ci/dependency_floors.py) "pytest>=7" "mcap-ros2-support==0.5.0"
	$(FLOORS)/bin/pip install --quiet --no-deps -e .
	$(FLOORS)/bin/pip list --format=freeze | grep -iE '^(numpy|scipy|pykdtree|plyfile|pypcd4|rosbags|mcap|tqdm)=='
	$(FLOORS)/bin/python -m pytest -q -p no:cacheprovider test/bag --ignore=test/bag/test_bag_signals.py

# ruff (lint and format) over the tree; mypy: the core strict, the ROS side and the benchmark typed.
lint: $(STAMP)
	$(BIN)/ruff check .
	$(BIN)/ruff format --check .
	$(BIN)/mypy --strict frisicp_core
	$(BIN)/mypy frisicp_ros frisicp_bench

# The fault campaign (tools/fuzz/run.py): hostile files, damaged bags, signal storms, hostile
# messages and parameters to a live node (loopback DDS, domain 171); niced, seeded, bounded by
# MINUTES (default 10). Counts in docs/reliability.md.
fuzz: $(STAMP)
	$(BIN)/python tools/fuzz/run.py --minutes $(or $(MINUTES),10) $(if $(ONLY),--only $(ONLY))

# config/frisicp.yaml and the parameter tables of docs/node.md and README.md are generated from the
# settings table (frisicp_ros/stream/settings.py).
config: $(STAMP)
	$(BIN)/python -m frisicp_ros.stream.settings > config/frisicp.yaml.new && mv config/frisicp.yaml.new config/frisicp.yaml
	$(BIN)/python -m frisicp_ros.stream.settings --markdown docs/node.md README.md

# register in aligned bidirectional passes, cold and warm (docs/core_speed.md); Open3D side by side
# when installed. One OpenMP thread, as the node and the bag workers run. Then register with
# OpenMP's default threads against OMP_NUM_THREADS=1, interleaved, one busy process beside
# (docs/default_threads.md): the core limits its own threads, so the ratio should be ~1.
bench: $(STAMP)
	OMP_NUM_THREADS=1 $(BIN)/python benchmarks/core_speed.py
	nice -n 10 env -u OMP_NUM_THREADS $(BIN)/python benchmarks/default_threads.py

# Trustworthy answers on the real scenes (crops, sparse maps, frames, scan pairs, turned scans,
# unrelated objects, jumps): right or honestly unreliable, calibration -> docs/trustworthy.md.
bench-trust: $(STAMP)
	nice -n 5 $(BIN)/python benchmarks/trustworthy.py --jobs $(or $(JOBS),2)

# Every script in benchmarks/ once with --quick, two at a time (tools/bench_smoke.py; JOBS=1 for one):
# reports under build/ (docs/ keeps the full runs' figures), so a script that no longer runs
# against today's code fails here (CI). A script lacking its data or an optional package (ROS,
# Open3D) says so and skips that part.
bench-smoke: $(STAMP)
	$(BIN)/python tools/bench_smoke.py --jobs $(or $(JOBS),2)

# The paper's experiments on ../shared/data -> docs/benchmarks/ (tables, JSON, figures).
# One thread per method: on a shared 2-core machine OpenMP's idle-waiting threads make
# timings erratic (small KD-tree queries become hundreds of times slower under load).
bench-paper: $(STAMP)
	OMP_NUM_THREADS=1 $(BIN)/frisicp bench

# The CI subset (< 2 min): keeps the benchmark code working; writes build/bench-quick/.
bench-paper-quick: $(STAMP)
	OMP_NUM_THREADS=1 $(BIN)/frisicp bench --quick

# Partial overlap (scans in the bunny map, the map in scans, scan pairs, outliers, noise) with the
# default config, Open3D beside it when installed -> docs/partial_overlap.md; JOBS=1 for steadier timings.
bench-partial: $(STAMP)
	$(BIN)/python benchmarks/partial_overlap.py --jobs $(or $(JOBS),2)

# register_node at 10 Hz with 100k-point clouds, default parameters, a static then a moving truth
# (docs/node.md); DURATION=300 for the growth check, TRUTH=static|moving for one of them.
bench-node: $(STAMP)
	$(BIN)/python benchmarks/node_latency.py --duration $(or $(DURATION),60) --truth $(or $(TRUTH),both)

# Big maps (docs/big_map.md): indexing 100k-4M-point maps, tracking cost against maps of 100k, 1M
# and 4M points, a cold registration of a 20k crop onto rs1 in aligned passes. ~15 min, niced.
bench-big-map: $(STAMP)
	nice -n 10 $(BIN)/python benchmarks/big_map.py

# register_node with a latched 2M-point map, 100k-point scans at 10 Hz and an initial guess
# (docs/node.md, Big maps); DURATION=300 for the memory check.
bench-big-map-node: $(STAMP)
	nice -n 10 $(BIN)/python benchmarks/big_map_node.py --duration $(or $(DURATION),60)

# frisicp bag throughput, --jobs 1 and 2, on 200 pairs of 30k-point clouds (docs/bag.md); PAIRS=20 for a look.
bench-bag: $(STAMP)
	$(BIN)/python benchmarks/bag_throughput.py --pairs $(or $(PAIRS),200)

# frisicp bag on a Dask cluster on this machine (1 and 2 workers) beside --jobs 1/2, the scheduling
# overhead per pair, LocalCluster's start-up and Ctrl-C beside the pool's (docs/bag.md); PAIRS=16 for a look.
bench-cluster: $(STAMP)
	nice -n 10 $(BIN)/python benchmarks/cluster_throughput.py --pairs $(or $(PAIRS),60)

clean:
	rm -rf $(VENV) $(FLOORS) build install log *.egg-info
