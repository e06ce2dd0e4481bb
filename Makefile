# Every target sets itself up from nothing: the venv is created and the project installed on demand.
PYTHON ?= python3
VENV   := .venv
BIN    := $(VENV)/bin
STAMP  := $(VENV)/.installed-stamp
RUNS   ?= runs

.PHONY: install run test test-slow lint bench table figures studies paper ablation clean

$(STAMP): pyproject.toml
	$(PYTHON) -m venv $(VENV)
	$(BIN)/python -m pip install --quiet --upgrade pip
	$(BIN)/python -m pip install --quiet -e ".[dev,bench]"
	touch $(STAMP)

install: $(STAMP)

## The main job: AMEX on Task 3 (moving goal + obstacle), 150 environments (~3 min).
run: $(STAMP)
	$(BIN)/amex-run task=3 method=amex

## Fast tests (the default suite, < 5 min on 2 cores).
test: $(STAMP)
	$(BIN)/python -m pytest -q

## Long end-to-end tests (marked slow).
test-slow: $(STAMP)
	$(BIN)/python -m pytest -q -m slow

lint: $(STAMP)
	$(BIN)/ruff check amex tests analysis examples
	$(BIN)/mypy amex

## Medians of the inner step, an episode, the reference plan and every method's outer step.
bench: $(STAMP)
	$(BIN)/python -m amex.bench
	$(BIN)/python -m analysis.bench_amex
	$(BIN)/python -m analysis.bench_dmp

## The paper's Fig. 5 from every episodes.csv under $(RUNS), into analysis/out/.
table: $(STAMP)
	$(BIN)/python -m analysis.table $(RUNS)

## The paper's figures (Fig. 2 from AMEX itself, Fig. 4 and Fig. 6 analogues) into analysis/out/.
figures: $(STAMP)
	$(BIN)/python -m analysis.figures

## Beyond the paper: robustness (goal speed, noise, prediction) and pr2_like studies (~1.5 h).
studies: $(STAMP)
	$(BIN)/python -m analysis.robustness --episodes 50
	$(BIN)/python -m analysis.pr2 --episodes 30

## The whole comparison: 4 tasks x 3 methods x 150 environments, then the table.
## EXPERIMENT=original runs the authors' setup (conf/experiment/original.yaml) into runs/paper_original.
## Re-running resumes: recorded episodes are kept and skipped.
EXPERIMENT ?=
PAPER_DIR ?= runs/paper$(if $(EXPERIMENT),_$(EXPERIMENT))
paper: $(STAMP)
	$(BIN)/amex-run -m $(if $(EXPERIMENT),experiment=$(EXPERIMENT)) task=1,2,3,4 method=amex,dmp,cr hydra.sweep.dir=$(PAPER_DIR)
	$(BIN)/python -m analysis.table $(PAPER_DIR)

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
