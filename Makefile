# Two commands: `make run` and `make test`. Both create .venv on first use, with only python3 present.
PYTHON ?= python3
VENV   := .venv
BIN    := $(VENV)/bin
STAMP  := $(VENV)/.installed

.PHONY: run test lint bench clean

$(STAMP): pyproject.toml
	$(PYTHON) -m venv $(VENV)
	$(BIN)/python -m pip install --quiet --upgrade pip
	$(BIN)/python -m pip install --quiet -e '.[test,bench]'
	touch $(STAMP)

# The main job. Until the whole stack lands this plans the paper's reference scenario and draws it.
run: $(STAMP)
	$(BIN)/python -m planner examples/reference_buoys.geojson --method chnn-ga --seed 1 --plot bench/results/reference_route.png
	@echo "route drawn in bench/results/reference_route.png"

test: $(STAMP)
	$(BIN)/python -m ruff check .
	$(BIN)/python -m pytest -n 2 --dist loadgroup

lint: $(STAMP)
	$(BIN)/python -m ruff check .
	$(BIN)/python -m ruff format --check .

bench: $(STAMP)
	$(BIN)/python bench/planner.py

clean:
	rm -rf $(VENV) .pytest_cache .ruff_cache
