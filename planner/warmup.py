"""Compile (or load from numba's on-disk cache) every kernel the planner's three kinds of plan run: one tour
(CHNN-GA: edge crossover, 2-opt / Or-opt local search, iterated local search), sorties under an energy budget
(Prins' split, the sortie search) and a fleet's min-max plan (the min-max split, the fleet search).

Why: a kernel compiles on its first call, and that call's clock is already running: on a cold cache a 2 s
fleet plan took 56 s. A service calls `warm_up()` before it takes requests; with the cache on disk it only loads
the compiled code (well under a second), so doing it on every start costs little.

Each step runs the real entry point (or the kernel itself, with the argument types the planner passes it) on a
tiny instance: numba compiles one machine-code version per argument types, and the version the requests need
is the one compiled here (tests/test_gcs_planning_warmup.py checks that real plans compile nothing more).
"""

from __future__ import annotations

import numpy as np

from planner import fleet, local_search, sorties
from planner.edge_crossover import edge_crossover


def _tour_kernels() -> None:
    """The single-tour kernels: local_search.warm_up's, plus those the GA calls from Python (tour_length, the
    edge crossover), which a plan reaches only with more buoys than the exact method takes and, for the
    crossover, only in some generations: on a tiny instance they are called directly."""
    local_search.warm_up()
    rng = np.random.default_rng(0)
    points = rng.uniform(0.0, 1.0, (12, 2))
    dist = np.sqrt(((points[:, None, :] - points[None, :, :]) ** 2).sum(-1))
    neighbours = local_search.neighbour_lists(dist, 5)
    first, second = np.arange(12, dtype=np.int64), rng.permutation(12).astype(np.int64)
    local_search.tour_length(first, dist)
    edge_crossover(first, second, np.zeros_like(dist), dist, neighbours, 0)


def warm_up() -> None:
    """Compile or load every planner kernel: single-tour, sortie (energy) and fleet planning. Seconds to a
    minute on a cold cache (all CPU, holding the GIL for much of it: run it before serving, not beside it)."""
    _tour_kernels()
    sorties.warm_up()
    fleet.warm_up()


if __name__ == "__main__":  # `make` runs it once after installing, so no process pays the first compilation
    import time

    started = time.perf_counter()
    warm_up()
    print(f"planner kernels compiled or loaded in {time.perf_counter() - started:.1f} s")
