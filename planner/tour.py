"""The planner's one entry point: ``plan_tour``.

Methods:
- ``"chnn-ga"``: the paper's CHNN-GA (Algorithm 2) with memetic 2-opt + Or-opt repair (planner.chnn_ga).
- ``"chnn"``: the CHNN alone (Algorithm 1): a batch of networks from random states, the shortest valid tour;
  no GA, no local search. Up to CHNN_MAX_NODES nodes (m^2 neurons get slow past that).
- ``"exact"``: Held-Karp, optimal, up to EXACT_MAX_NODES = 16 nodes.
- ``"auto"``: exact when n <= AUTO_EXACT_MAX_NODES (16 nodes: Held-Karp takes ~30 ms there and is optimal),
  else chnn-ga.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field

import numpy as np

from planner import chnn
from planner.chnn_ga import GAParameters, chnn_ga
from planner.distances import check_distance_matrix, check_points, closed_tour_length, euclidean_matrix
from planner.errors import InputError, PlannerError, TooLargeError
from planner.exact import EXACT_MAX_NODES, held_karp
from planner.methods import METHODS

AUTO_EXACT_MAX_NODES = EXACT_MAX_NODES
CHNN_MAX_NODES = 60


class NoValidTourError(PlannerError):
    """The CHNN alone ended on no valid tour within its time limit (only method="chnn")."""


@dataclass
class PlanResult:
    """A closed tour from the depot (node 0) and back."""

    order: list[int]  # permutation of range(n) starting with 0
    length: float  # closed tour length, in the units of the points or the distance matrix
    method: str  # the method that produced it ("auto" resolves to "exact" or "chnn-ga")
    elapsed_s: float
    history: list[dict] = field(default_factory=list)  # per generation: best_length, energy trace, ...


def _pure_chnn(
    dist: np.ndarray, seed: int, time_limit_s: float, batch: int = 8, params: chnn.CHNNParameters = chnn.VALID_TOURS
) -> tuple[list[int], list[dict]]:
    """Algorithm 1 alone: batches of networks until one ends valid (or time runs out); the shortest."""
    n = len(dist)
    if n - 1 > CHNN_MAX_NODES:
        raise TooLargeError(f"the pure CHNN takes at most {CHNN_MAX_NODES + 1} nodes; got {n}")
    rng = np.random.default_rng(seed)
    free = np.arange(1, n)
    d, d_start, d_end = chnn.normalised(dist, free, 0, 0)
    started = time.perf_counter()
    history: list[dict] = []
    best: list[int] | None = None
    best_length = np.inf
    while best is None and time.perf_counter() - started < time_limit_s:
        run = chnn.run_chnn(d, d_start, d_end, params, chnn.initial_state(batch, n - 1, params, rng))
        valid = 0
        for k in range(batch):
            order = chnn.decode(run.v[k])
            if order is None:
                continue
            valid += 1
            tour = [0, *free[order].tolist()]
            length = closed_tour_length(tour, dist)
            if length < best_length:
                best, best_length = tour, length
        history.append(
            {
                "generation": len(history),
                "best_length": float(best_length),
                "chnn_children": batch,
                "chnn_valid": valid,
                "energy": run.energy[:, 0].tolist(),
            }
        )
    if best is None:
        runs = batch * len(history)
        raise NoValidTourError(f"the CHNN found no valid tour in {time_limit_s} s ({runs} runs)")
    return best, history


def plan_tour(
    points=None,
    method: str = "chnn-ga",
    seed: int = 0,
    time_limit_s: float = 2.0,
    distance=None,
    ga: GAParameters | None = None,
) -> PlanResult:
    """Plan the closed tour from node 0 (the depot) through every other node and back.

    points: (n, 2) array of planar coordinates (metres), node 0 the depot; or None with ``distance``, an
    (n, n) precomputed distance matrix (e.g. TSPLIB's integer distances), which then defines the lengths.
    Raises InputError (fewer than 2 nodes, duplicates, non-finite values, unknown method) and TooLargeError
    (more nodes than the method takes).
    """
    started = time.perf_counter()
    if method not in METHODS:
        raise InputError(f"unknown method {method!r}; use one of {', '.join(METHODS)}")
    if not (isinstance(time_limit_s, int | float) and np.isfinite(time_limit_s) and time_limit_s > 0):
        raise InputError(f"time limit must be a positive number of seconds, got {time_limit_s!r}")
    if distance is not None:
        dist = check_distance_matrix(distance)
        if points is not None and len(check_points(points)) != len(dist):
            raise InputError("points and distance matrix disagree on the number of nodes")
    elif points is not None:
        dist = euclidean_matrix(check_points(points))
    else:
        raise InputError("give points or a distance matrix")
    n = len(dist)
    if method == "auto":
        method = "exact" if n <= AUTO_EXACT_MAX_NODES else "chnn-ga"
    history: list[dict] = []
    if method == "exact":
        order, _ = held_karp(dist)
    elif method == "chnn":
        order, history = _pure_chnn(dist, seed, time_limit_s)
    else:
        result = chnn_ga(dist, seed=seed, time_limit_s=time_limit_s, ga=ga)
        order, history = result.order, result.history
    return PlanResult(
        order=[int(i) for i in order],
        length=closed_tour_length(order, dist),
        method=method,
        elapsed_s=time.perf_counter() - started,
        history=history,
    )
