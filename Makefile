# Every target sets itself up from nothing: the venv is created and the project installed on demand.
PYTHON ?= python3
VENV   := .venv
BIN    := $(VENV)/bin
STAMP  := $(VENV)/.installed-stamp
RUNS   ?= runs

.PHONY: install run test test-slow lint bench figures clean

$(STAMP): pyproject.toml
	$(PYTHON) -m venv $(VENV)
	$(BIN)/python -m pip install --quiet --upgrade pip
	$(BIN)/python -m pip install --quiet -e ".[dev,bench]"
	touch $(STAMP)

install: $(STAMP)

## The main job: AMEX's reference scene and its hardest paper task, a few environments each.
run: $(STAMP)
	$(BIN)/amex-run task=0 method=track episodes=10

## Fast tests (the default suite, < 5 min on 2 cores).
test: $(STAMP)
	$(BIN)/python -m pytest -q

## Long end-to-end tests (marked slow).
test-slow: $(STAMP)
	$(BIN)/python -m pytest -q -m slow

lint: $(STAMP)
	$(BIN)/ruff check amex tests analysis
	$(BIN)/mypy amex

## Medians of the inner step, an episode, the reference plan and every method's outer step.
bench: $(STAMP)
	$(BIN)/python -m amex.bench

clean:
	rm -rf $(VENV) .pytest_cache .ruff_cache .mypy_cache
