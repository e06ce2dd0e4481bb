# Every target sets itself up from nothing: the venv is created and the project installed on demand.
PYTHON ?= python3
VENV   := .venv
BIN    := $(VENV)/bin
STAMP  := $(VENV)/.installed-stamp
RUNS   ?= runs

.PHONY: install kernels run test test-slow test-kernels test-viewer test-live render-deps lint bench table figure-runs figures studies paper ablation ablation-table baselines clean

$(STAMP): pyproject.toml
	$(PYTHON) -m venv $(VENV)
	$(BIN)/python -m pip install --quiet --upgrade pip
	$(BIN)/python -m pip install --quiet -e ".[dev,bench]"
	$(BIN)/python -m amex.app.warm  # every Numba kernel compiled once, into its cache
	$(BIN)/python -m amex.app.build_kernels || echo "make install: runs use Numba's JIT"
	touch $(STAMP)

# The ahead-of-time kernels built again where their sources changed since (a no-op otherwise).
FRESH_KERNELS = $(BIN)/python -m amex.app.build_kernels --if-stale || true

install: $(STAMP)

## The episode loop's kernels compiled ahead of time again, after an edit of their sources.
kernels: $(STAMP)
	$(BIN)/python -m amex.app.build_kernels

## The main job: AMEX on Task 3 (moving goal + obstacle), 150 environments (~3 min).
run: $(STAMP)
	@$(FRESH_KERNELS)
	$(BIN)/amex-run task=3 method=amex

## Fast tests (the default suite, < 5 min on 2 cores).
test: $(STAMP)
	@$(FRESH_KERNELS)
	$(BIN)/python -m pytest -q

## The tests of logs, the episode store, the plan cache and CR's compiled kinematics again under
## other BLAS kernels than this machine's: no test may depend on bits that follow the kernel.
KERNEL_TESTS := tests/log/test_log.py tests/log/test_faults_logs.py tests/experiment/test_store.py \
  tests/experiment/test_faults_store.py tests/plan/test_faults_cache.py \
  tests/plan/test_kinematics_kernels.py tests/plan/test_blas.py tests/plan/test_assembly.py
# SkylakeX too where the CPU has AVX-512 (OpenBLAS cannot run it elsewhere).
KERNELS := Haswell Prescott $(shell grep -qw avx512f /proc/cpuinfo 2>/dev/null && echo SkylakeX)
test-kernels: $(STAMP)
	for kernel in $(KERNELS); do \
	  OPENBLAS_CORETYPE=$$kernel $(BIN)/python -m pytest -q $(KERNEL_TESTS) || exit $$?; \
	done

## Long end-to-end tests (marked slow; the slow docs checks run in make docs).
test-slow: $(STAMP)
	$(BIN)/python -m pytest -q -m slow --ignore=tests/docs

## Logs in a real browser viewer: Debian's chromium and Foxglove Studio 1.48 (npm), installed here
## if missing, open logged episodes headless; every topic listed, no player problems (~3 min).
VIEWER := tests/viewer
$(VIEWER)/node_modules/.installed: $(VIEWER)/package.json $(VIEWER)/package-lock.json
	@command -v chromium >/dev/null || { apt-get update -qq && \
	  DEBIAN_FRONTEND=noninteractive apt-get install -y -qq --no-install-recommends chromium; }
	cd $(VIEWER) && npm ci --no-audit --no-fund --loglevel=error
	touch $@

test-viewer: $(STAMP) $(VIEWER)/node_modules/.installed
	$(BIN)/python -m pytest -q -m viewer -p no:cacheprovider

## The live page (amex-live) in a real browser: Debian's chromium, installed here if missing,
## driven by playwright (pip extra `browser`; no browser download): the goal gizmo dragged with
## the mouse for AMEX, DMP and CR, screenshots in $(LIVE_SHOTS) (~2 min).
LIVE_SHOTS ?= runs/test-live
BROWSER_STAMP := $(VENV)/.browser-stamp
$(BROWSER_STAMP): $(STAMP)
	@command -v chromium >/dev/null || { apt-get update -qq && \
	  DEBIAN_FRONTEND=noninteractive apt-get install -y -qq --no-install-recommends chromium; }
	$(BIN)/python -m pip install --quiet -e ".[dev,bench,browser]"
	touch $@

test-live: $(BROWSER_STAMP)
	AMEX_LIVE_SHOTS=$(LIVE_SHOTS) $(BIN)/python -m pytest -q -m live -p no:cacheprovider -s

## Headless OpenGL for amex-log video and Fig. 4's render: Debian's EGL (Mesa), if missing.
render-deps: $(STAMP)
	@$(BIN)/python -c "from amex.log.render import gl_context; gl_context(8, 8).free()" 2>/dev/null || \
	  { apt-get update -qq && DEBIAN_FRONTEND=noninteractive apt-get install -y -qq \
	    --no-install-recommends libegl1 libegl-mesa0 libgl1-mesa-dri; }

lint: $(STAMP)
	$(BIN)/ruff check amex tests analysis examples
	$(BIN)/mypy amex

## Medians of the inner step, an episode, the reference plan and every method's outer step.
bench: $(STAMP)
	@$(FRESH_KERNELS)
	$(BIN)/python -m amex.app.bench
	$(BIN)/python -m analysis.bench_amex
	$(BIN)/python -m analysis.bench_dmp

## The paper's Fig. 5 from every episodes.csv under $(RUNS), into analysis/out/, with the claims as
## test verdicts (docs/statistics.md); compute.md from reruns under runs/compute/ if any.
table: $(STAMP)
	$(BIN)/python -m analysis.table $(RUNS)
	@if [ -d runs/paper_original ] && [ -d runs/paper ]; then \
	  $(BIN)/python -m analysis.compare original=runs/paper_original ours=runs/paper; \
	else echo "(make paper and make paper EXPERIMENT=original give the side-by-side analysis/out/compare.md)"; fi
	@if [ -d runs/compute ] && [ -n "$$(ls runs/compute)" ]; then \
	  $(BIN)/python -m analysis.compute runs/compute/*; \
	else echo "(reruns of a cell set under runs/compute/<label>/ give analysis/out/compute.md)"; fi

## The ablation's steps side by side (analysis/out/ablation.md), after make ablation and make paper.
ablation-table: $(STAMP)
	$(BIN)/python -m analysis.compare --name ablation.md original=runs/paper_original \
	  1_harness=$(ABLATION_DIR)/1_harness 2_controller=$(ABLATION_DIR)/2_controller \
	  3_methods=$(ABLATION_DIR)/3_methods 4_dynamic=$(ABLATION_DIR)/4_dynamic ours=runs/paper

## The logged runs Fig. 4 and Fig. 6 are drawn from (conf/experiment/fig4.yaml, fig6.yaml): into
## runs/fig4/ and runs/fig6/, a few seconds; again resumes (nothing left to run).
figure-runs: $(STAMP)
	$(BIN)/amex-run -m experiment=fig4
	$(BIN)/amex-run experiment=fig6

## Fig. 5 as plots from the runs under $(RUNS), then Fig. 2 (from AMEX itself), Fig. 4 and Fig. 6
## analogues (from figure-runs' logs), into analysis/out/ (PNG and PDF).
figures: figure-runs
	$(BIN)/python -m analysis.figures --runs $(RUNS)

## Beyond the paper: the robustness (goal speed, noise, prediction) and pr2_like studies, each a
## sweep on the launcher (conf/study/*.yaml; make studies again resumes), then their reports.
studies: $(STAMP)
	$(BIN)/amex-run -m study=robustness
	$(BIN)/amex-run -m study=pr2_like
	$(BIN)/python -m analysis.robustness runs/robustness
	$(BIN)/python -m analysis.pr2 runs/pr2_like

## The whole comparison: 4 tasks x 3 methods x 150 environments, then the table.
## EXPERIMENT=original runs the authors' setup (conf/experiment/original.yaml) into runs/paper_original.
## SHARDS=K splits every cell over K jobs (a new directory: shards and whole runs do not mix).
## Re-running resumes: recorded episodes are kept and skipped.
EXPERIMENT ?=
SHARDS ?=
PAPER_DIR ?= runs/paper$(if $(EXPERIMENT),_$(EXPERIMENT))
paper: $(STAMP)
	@$(FRESH_KERNELS)
	$(BIN)/amex-run -m $(if $(EXPERIMENT),experiment=$(EXPERIMENT)) task=1,2,3,4 method=amex,dmp,cr $(if $(SHARDS),shards=$(SHARDS)) hydra.sweep.dir=$(PAPER_DIR)
	$(BIN)/python -m analysis.table $(PAPER_DIR)

## AMEX against today's reactive methods (issue #26, conf/study/baselines.yaml): every method on
## Tasks 1-4, the Panda at 150 environments, the UR5 and chain7 at 30, one run per (method, robot,
## task) under runs/baselines (resumes; METHOD=<name> runs only that method's runs), then the tables
## into analysis/out/ (docs: the runs committed under docs/data/runs/baselines, make docs-tables).
METHOD ?=
baselines: $(STAMP)
	$(BIN)/amex-run -m study=baselines $(if $(METHOD),method=$(METHOD))
	$(BIN)/python -m analysis.baselines runs/baselines

## From the authors' setup to ours one factor at a time (conf/experiment/ablation/): step 0 is
## `make paper EXPERIMENT=original` (runs/paper_original), steps 1-4 go to runs/ablation/, step 5
## is `make paper` (runs/paper). Resumable like every sweep.
ABLATION_DIR ?= runs/ablation
ablation: $(STAMP)
	$(BIN)/amex-run -m experiment=original task=1,2,3,4 method=amex,dmp,cr hydra.sweep.dir=runs/paper_original
	for step in 1_harness 2_controller 3_methods 4_dynamic; do \
	  $(BIN)/amex-run -m experiment=ablation/$$step task=1,2,3,4 method=amex,dmp,cr \
	    hydra.sweep.dir=$(ABLATION_DIR)/$$step || exit $$?; \
	done

clean:
	rm -rf $(VENV) .pytest_cache .ruff_cache .mypy_cache

## The documentation site (MkDocs + Material + mkdocstrings) into site/: the docs tests (generated
## tables, project files, the site's checks), then a strict build, so that a warning, a link to a
## missing page or a missing anchor fails it. The docs extra is installed on demand.
.PHONY: docs docs-serve docs-tables
DOCS_STAMP := $(VENV)/.docs-stamp
$(DOCS_STAMP): $(STAMP) pyproject.toml
	$(BIN)/python -m pip install --quiet -e ".[dev,bench,docs]"
	touch $(DOCS_STAMP)

docs: $(DOCS_STAMP)
	$(BIN)/python -m pytest -q -m "not viewer and not live" tests/docs
	NO_MKDOCS_2_WARNING=1 $(BIN)/mkdocs build --strict --site-dir site

## The site on http://127.0.0.1:8000/ (this machine only), rebuilt on every change.
docs-serve: $(DOCS_STAMP)
	NO_MKDOCS_2_WARNING=1 $(BIN)/mkdocs serve --dev-addr 127.0.0.1:8000

## The results tables the pages include (docs/generated/), written again by the analysis commands
## from the runs committed under docs/data/ (tests/docs/ fails when they differ).
docs-tables: $(STAMP)
	$(BIN)/python docs/hooks.py
