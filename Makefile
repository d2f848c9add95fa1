# softflow: every result of the paper from one command.
#   make reproduce   run every notebook (PROFILE=paper by default; PROFILE=ci for minutes)
#   make test        unit tests + nbval of the committed notebooks (ci profile)
#   make study       recompute every cell of the studies (notebooks 08-11) on a local Dask cluster
#   make strip       clean the committed notebooks after regenerating their ci outputs
#   make portability make test on fresh clones under three forced kernel paths
SHELL := /bin/bash
PYTHON_BASE ?= python3.11
VENV := .venv
PY := $(VENV)/bin/python
STAMP := $(VENV)/.lock-installed
PROFILE ?= paper
BENCH_PROFILE ?= ci
NOTEBOOKS := $(sort $(wildcard notebooks/[0-9]*.ipynb))

.PHONY: venv test lint reproduce readme site loop-parts loop-bound study bench bench-setup bench-reproduce portability lab clean lock strip

venv: $(STAMP)

# Every Python process of a run (each notebook's kernel, each pytest lane, Dask worker and CLI
# call in the tests) imports torch, pandas, scipy and matplotlib. With PYTHONDONTWRITEBYTECODE set
# (as on the machines this is developed and tested on) and no bytecode installed, each of them
# compiled those from source again: about 10 CPU-s a process here. The targets write the bytecode
# of what is imported, once.
export PYTHONDONTWRITEBYTECODE :=

# Rebuilt whenever the lock changes; a half-built venv never gets the stamp. --no-compile: Python
# compiles a module when it is first imported and keeps its bytecode (the export above), so the
# install does not compile the ones never used (half the install's time).
$(STAMP): environment.lock pyproject.toml
	rm -rf $(VENV)
	$(PYTHON_BASE) -m venv $(VENV)
	$(PY) -m pip install --quiet --no-compile -r environment.lock
	$(PY) -m pip install --quiet --no-deps --no-build-isolation -e .
	cp environment.lock $(STAMP)

NBVAL := --nbval --nbval-current-env --nbval-sanitize-with tests/nbval_sanitize.cfg
# make test runs two lanes side by side on the two cores, then the notebook that reads every
# result: most unit tests with the twin's notebooks (06; 10 closes the loop on 06's twin models,
# 13 reuses its dataset), and the other notebooks in order (04 reads 03's results, 08 03's and
# 04's, 11 09's fwd_lambda rows) with the unit tests of TESTS_B, which even the lanes' times
# (figures/bench/notebooks.csv); the ci cells that test_shipped_rows recomputes make the ci
# datasets and the twin's models early, which 02 and 06 then find. One
# BLAS thread per lane: two lanes of two threads each spin against each other on two cores.
LAST := notebooks/07_comparison_tables.ipynb
LANE_A := notebooks/06_hardware_replay.ipynb notebooks/10_closed_loop.ipynb notebooks/13_recorded_runs.ipynb
LANE_B := $(filter-out $(LANE_A) $(LAST),$(NOTEBOOKS))
TESTS_B := tests/test_recorded_study.py tests/test_friction.py tests/test_shipped_rows.py tests/test_loop.py
test: export OMP_NUM_THREADS = 1
test: export OPENBLAS_NUM_THREADS = 1
# glibc gives a freed large array back to the system and faults its pages in again at the next
# step's allocation (up to a fifth of the CPU time in the statics went to the kernel); keeping
# freed memory in the process instead saved 13 % of a static lift's and 7 % of the twin tests'
# wall time here, bit for bit the same results.
test reproduce study bench-setup: export MALLOC_MMAP_THRESHOLD_ = 134217728
test reproduce study bench-setup: export MALLOC_TRIM_THRESHOLD_ = 536870912
test reproduce study bench-setup: export MALLOC_TOP_PAD_ = 67108864
test: $(STAMP) lint
	mkdir -p build
	$(PY) -m pytest $(LANE_B) $(TESTS_B) $(NBVAL) -p no:cacheprovider > build/lane-b.log 2>&1 & \
	$(PY) -m pytest tests $(addprefix --ignore=,$(TESTS_B)) $(LANE_A) $(NBVAL); a=$$?; \
	wait $$!; b=$$?; cat build/lane-b.log; \
	$(PY) -m pytest $(LAST) $(NBVAL) -p no:cacheprovider; last=$$?; \
	exit $$(( a || b || last ))

# Style and architecture: ruff (lint and format, pyproject.toml) and the import contract
# (layers point one way; models never import the rod; control never imports training).
lint: $(STAMP)
	$(VENV)/bin/ruff check softflow tests benchmarks notebooks examples
	$(VENV)/bin/ruff format --check softflow tests benchmarks examples
	$(VENV)/bin/lint-imports

# The committed notebooks are their ci run without its run record. Regenerate one with
#   .venv/bin/papermill --cwd notebooks -p profile ci notebooks/NN_x.ipynb /tmp/NN_x.ipynb
# and copy it back; this then drops the execution timestamps, papermill's metadata and its
# injected-parameters cell, and re-encodes the figures losslessly (tests/test_notebooks_clean.py
# fails on any of those left, or on more than 1.7 MB of notebooks in all).
strip: $(STAMP)
	$(PY) tests/strip_notebooks.py

# 07 reads every other notebook's results: it runs last.
reproduce: $(STAMP)
	mkdir -p build/notebooks/$(PROFILE)
	for nb in $(filter-out $(LAST),$(NOTEBOOKS)) $(LAST); do \
		echo "== $$nb ($(PROFILE))"; \
		$(VENV)/bin/papermill --cwd notebooks -p profile $(PROFILE) "$$nb" "build/notebooks/$(PROFILE)/$$(basename $$nb)" || exit 1; \
	done
	$(if $(filter paper,$(PROFILE)),$(PY) -m softflow.report.readme)
	$(PY) -m softflow.report.site --notebooks build/notebooks/$(PROFILE)

# The README's result block, from the shipped study rows (softflow/report/templates/studies/).
readme: $(STAMP)
	$(PY) -m softflow.report.readme

# The companion site, build/site/index.html: the results page and the notebooks make reproduce
# executed (build/notebooks/paper/), as static HTML; nothing is run again.
site: $(STAMP)
	$(PY) -m softflow.report.site

# The loop's filter and predictors on the ASL trunk's held-out run (about a minute)
loop-parts: $(STAMP)
	$(PY) -m softflow.studies.trunk_loop

# How much of the open loop's error any feedback through the rig's delay can remove, on the loop
# study's pilot (about 3 minutes)
loop-bound: $(STAMP)
	$(PY) -m softflow.studies.loop_bound

# Every cell of the studies, recomputed (not read from figures/sweeps/) and cached in
# data/sweeps/, so an interrupted run resumes; SCHEDULER_FILE=s.json runs them on your cluster.
STUDIES := table1 protocol data_size ambiguity fwd_lambda design closed_loop twin_burst recorded two_segment trunk loop
study: $(STAMP)
	for s in $(STUDIES); do \
		$(PY) -m softflow sweep $$s --profile $(PROFILE) --recompute $(if $(SCHEDULER_FILE),--scheduler-file $(SCHEDULER_FILE)) || exit 1; \
	done

ELASTICA := .venv-elastica/.installed
$(ELASTICA): benchmarks/requirements-elastica.txt
	rm -rf .venv-elastica
	$(PYTHON_BASE) -m venv .venv-elastica
	.venv-elastica/bin/pip install --quiet -r benchmarks/requirements-elastica.txt
	touch $(ELASTICA)

bench: $(STAMP) $(ELASTICA)  # PyElastica is a benchmark-only dependency, in its own venv
	$(PY) benchmarks/bench_simulator.py
	$(PY) benchmarks/bench_two_segment.py
	$(PY) benchmarks/bench_planning.py  # the shipped paper models, as a user runs them
	$(PY) benchmarks/bench_training.py --profile $(BENCH_PROFILE)
	$(PY) benchmarks/bench_sweep.py
	$(PY) benchmarks/bench_loop.py
	$(PY) benchmarks/bench_recorded_loop.py  # the loop study's models: its paper sweep first
	$(PY) benchmarks/bench_quick_profile.py  # what the ci and quick budgets buy on the trunk's runs

# What a newcomer waits for (long: about as much as make test and a ci reproduce together):
# make venv + make test on a fresh clone, and each notebook's ci run.
bench-setup: $(STAMP)
	$(PY) benchmarks/bench_fresh_clone.py
	$(PY) benchmarks/bench_notebooks.py

# The main job as a new user meets it: make venv + make reproduce on a fresh clone of this commit,
# timed per notebook (about half an hour on two cores; run it with the cores free).
bench-reproduce: $(STAMP)
	$(PY) benchmarks/bench_reproduce.py

# make test on fresh clones under three kernel paths forced by the environment (native, generic
# x86-64, AVX2), one after the other (about three times make test): figures/bench/portability*.csv.
portability: $(STAMP)
	$(PY) benchmarks/bench_portability.py

lab: $(STAMP)
	$(VENV)/bin/jupyter lab notebooks

lock:  # refresh environment.lock from the current .venv (after adding a dependency)
	{ head -2 environment.lock; $(PY) -m pip freeze --exclude-editable; } > environment.lock.new && mv environment.lock.new environment.lock

clean:
	rm -rf build $(VENV) .venv-elastica .pytest_cache
