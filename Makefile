# Two commands: `make run` and `make test`. Both create .venv on first use, with only python3 present.
# `make test-fast` is the edit-test loop's subset (README, "Tests").
PYTHON ?= python3
VENV   := .venv
BIN    := $(VENV)/bin
STAMP  := $(VENV)/.installed
# Many integration tests wait on real-time flights (MAVSDK's example programs, test doubles), not on the CPU:
# six workers on two cores keep both cores busy while some of them wait (pytest 9:08 on a fresh clone), and every
# test polls on conditions with generous deadlines.
TEST_WORKERS ?= 6
# MAVSDK-Python 3.x (the gRPC wrapper bundling mavsdk_server) has the import name of the native mavsdk 4.x in
# .venv, so it lives in a venv of its own: tests/test_mavsdk_examples.py runs its example programs with it.
MAVSDK3_VENV  := .venv-mavsdk3
MAVSDK3_STAMP := $(MAVSDK3_VENV)/.installed
MAVSDK3_REQS  := tests/mavsdk_examples/requirements.txt

.PHONY: run test test-fast lint bench clean chromium postgresql

$(STAMP): pyproject.toml
	$(PYTHON) -m venv $(VENV)
	$(BIN)/python -m pip install --quiet --upgrade pip
	$(BIN)/python -m pip install --quiet -e '.[test,bench]'
	$(BIN)/python -m planner.warmup  # numba's on-disk cache: services, vehicles and tests then load, not compile
	$(BIN)/python -m sitl_quad.warmup
	touch $(STAMP)

# The last line proves the bundled mavsdk_server binary runs on this machine (it is a prebuilt executable).
$(MAVSDK3_STAMP): $(MAVSDK3_REQS)
	$(PYTHON) -m venv $(MAVSDK3_VENV)
	$(MAVSDK3_VENV)/bin/python -m pip install --quiet --upgrade pip
	$(MAVSDK3_VENV)/bin/python -m pip install --quiet -r $(MAVSDK3_REQS)
	$(MAVSDK3_VENV)/bin/python tests/mavsdk_examples/check_mavsdk_server.py
	touch $(MAVSDK3_STAMP)

# The main job: vehicle + ADRC offboard controller + service + map page, flying the paper's reference
# scenario in lockstep, then serving the map page at http://127.0.0.1:8000 until Ctrl-C.
run: $(STAMP)
	$(BIN)/python -m stack up --demo --real-time

test: $(STAMP) $(MAVSDK3_STAMP) chromium postgresql
	$(BIN)/python -m ruff check .
	$(BIN)/python -m ruff format --check .
	$(BIN)/lint-imports
	$(BIN)/python -m mypy
	env -u PYTHONDONTWRITEBYTECODE $(BIN)/python -m pytest -n $(TEST_WORKERS) --durations=15

# The tests that start no process, open no browser and fly nothing over loopback, the slow ones left out too: under
# a minute, for the edit-test loop (`make test` still runs everything). Two workers, one a core: each collects the
# whole suite (5 s) before it runs a test; here a third was no faster (31 s against 31 s), one process slower (49 s).
# Python's bytecode is let be written (here and in `test`), so pytest caches its assertion-rewritten modules: where
# the environment sets PYTHONDONTWRITEBYTECODE it rewrites them in every worker, and collecting takes 12 s, not 5.
FAST_TESTS := not slow and not integration and not browser
test-fast: $(STAMP)
	env -u PYTHONDONTWRITEBYTECODE $(BIN)/python -m pytest -n 2 -m "$(FAST_TESTS)"

# The browser tests drive Debian's Chromium (Playwright's own browser download does not work here).
chromium:
	@[ -x /usr/bin/chromium ] || { apt-get update -qq && DEBIAN_FRONTEND=noninteractive apt-get install -y -qq chromium >/dev/null; }

# The storage tests run against SQLite and against a throwaway PostgreSQL server started from Debian's binaries.
postgresql:
	@ls /usr/lib/postgresql/*/bin/initdb >/dev/null 2>&1 || { apt-get update -qq && DEBIAN_FRONTEND=noninteractive apt-get install -y -qq postgresql >/dev/null; }

lint: $(STAMP)
	$(BIN)/python -m ruff check .
	$(BIN)/python -m ruff format --check .
	$(BIN)/lint-imports
	$(BIN)/python -m mypy

bench: $(STAMP)
	$(BIN)/python -m bench.planner_bench
	$(BIN)/python -m bench.sitl
	$(BIN)/python -m bench.gcs_bench
	$(BIN)/python -m bench.sorties
	$(BIN)/python -m bench.failover

clean:
	rm -rf $(VENV) $(MAVSDK3_VENV) .pytest_cache .ruff_cache .mypy_cache
