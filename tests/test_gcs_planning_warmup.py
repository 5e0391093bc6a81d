"""Planning within the request's time limit: the service compiles (or loads from numba's cache) every planner kernel
before it takes a request (gcs.api.app's lifespan, planner.warmup), so no request pays for a compile its time limit
does not see. Before, a first fleet POST /missions with time_limit_s 2 answered after 56 s on a cold cache. The
first fleet POST on a cold start is tested on the installed wheel (tests/test_wheel_install.py), whose fresh
install compiles from an empty cache anyway: one cold compile in the suite, not two."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import pytest

from planner.scenario import reference_scenario

pytestmark = pytest.mark.integration  # the check runs in a fresh interpreter, which it must

BUOYS = [{"lat": lat, "lon": lon} for lat, lon in reference_scenario(1).buoys_lat_lon]


WARM_CACHE_CHECK = """
import json, sys, time
from fastapi.testclient import TestClient
from numba.core.registry import CPUDispatcher
from gcs.api.app import create_app
from gcs.settings import Settings

def compiled():
    kernels = {}
    for module in [m for n, m in sys.modules.items() if n.startswith("planner.")]:
        for name, value in vars(module).items():
            if isinstance(value, CPUDispatcher):
                kernels[f"{value.__module__}.{name}"] = sorted(map(str, value.signatures))
    return kernels

buoys = json.loads(sys.argv[2])
settings = Settings(data_dir=sys.argv[1], vehicles=["1=udpout:127.0.0.1:9", "2=udpout:127.0.0.1:9"])
started = time.perf_counter()
with TestClient(create_app(settings)) as client:
    startup_s = time.perf_counter() - started
    before = compiled()
    options = {"seed": 1, "time_limit_s": 0.5}
    answers = [
        client.post("/plans", json={"buoys": buoys, "planner": {**options, "method": "chnn-ga"}}),
        client.post("/plans", json={"buoys": buoys, "planner": options, "battery": {"capacity_mah": 1000}}),
        client.post("/missions", json={"buoys": buoys, "planner": options, "vehicles": [1, 2], "start": False}),
    ]
    after = compiled()
print(json.dumps({"status": [a.status_code for a in answers], "before": before, "after": after,
                  "startup_s": startup_s}))
"""


def test_the_warm_up_compiles_every_kernel_single_sortie_and_fleet_plans_run(tmp_path: Path) -> None:
    """In a fresh interpreter (nothing compiled before), the service's start compiles or loads every kernel
    a one-tour plan (CHNN-GA), a battery plan (sorties) and a fleet plan then run, with the argument types they
    run with: the three plans add no machine code (numba compiles one version per argument types)."""
    run = subprocess.run(
        [sys.executable, "-c", WARM_CACHE_CHECK, str(tmp_path), json.dumps(BUOYS)],
        capture_output=True,
        text=True,
        timeout=280,
    )
    assert run.returncode == 0, run.stderr
    result = json.loads(run.stdout.strip().splitlines()[-1])
    assert result["status"] == [200, 200, 201]
    added = {kernel: s for kernel, s in result["after"].items() if s != result["before"].get(kernel)}
    assert not added, f"the plans compiled what the warm-up left out: {added}"
    assert {"planner.fleet_search.search", "planner.sortie_search.search", "planner.edge_crossover.edge_crossover"} <= {
        kernel for kernel, signatures in result["before"].items() if signatures
    }
