# Two commands: `make run` and `make test`. Both create .venv on first use, with only python3 present.
PYTHON ?= python3
VENV   := .venv
BIN    := $(VENV)/bin
STAMP  := $(VENV)/.installed

.PHONY: run test lint bench clean chromium

$(STAMP): pyproject.toml
	$(PYTHON) -m venv $(VENV)
	$(BIN)/python -m pip install --quiet --upgrade pip
	$(BIN)/python -m pip install --quiet -e '.[test,bench]'
	touch $(STAMP)

# The main job: vehicle + ADRC offboard controller + service + map page, flying the paper's reference
# scenario in lockstep, then serving the map page at http://127.0.0.1:8000 until Ctrl-C.
run: $(STAMP)
	$(BIN)/python -m gcs up --demo

test: $(STAMP) chromium
	$(BIN)/python -m ruff check .
	$(BIN)/python -m ruff format --check .
	$(BIN)/lint-imports
	$(BIN)/python -m pytest -n 2

# The browser tests drive Debian's Chromium (Playwright's own browser download does not work here).
chromium:
	@[ -x /usr/bin/chromium ] || { apt-get update -qq && DEBIAN_FRONTEND=noninteractive apt-get install -y -qq chromium >/dev/null; }

lint: $(STAMP)
	$(BIN)/python -m ruff check .
	$(BIN)/python -m ruff format --check .
	$(BIN)/lint-imports

bench: $(STAMP)
	$(BIN)/python -m bench.planner_bench
	$(BIN)/python -m bench.sitl
	$(BIN)/python -m bench.gcs_bench

clean:
	rm -rf $(VENV) .pytest_cache .ruff_cache
