"""Energy-constrained multi-sortie routing: ``plan_sorties``.

When one battery (less its reserve) cannot cover every buoy, the buoys are split into sorties from the depot,
each within the budget, minimising the total flight time (or, by option, the total distance). The method:

1. route first: a giant tour through every buoy, by the single-sortie planner's local-search path (2-opt +
   Or-opt + ILS of planner.local_search on the symmetrised costs; ``giant_tour="chnn-ga"`` runs the CHNN-GA);
2. cluster second: Prins' exact split of that order, both ways round (planner.split);
3. improvement: inter- and intra-route local search (relocate, swap, 2-opt*, 2-opt, Or-opt; energy-checked,
   asymmetric costs) iterated with SISR ruin-and-recreate and simulated-annealing acceptance under the time
   limit (planner.sortie_search);
4. each sortie's order re-optimised by the single-sortie planner (Held-Karp when small, else CHNN-GA), kept
   only when shorter and still within the budget.

Every returned sortie is checked against the budget (``SortieCost.violations``). A buoy that cannot be served
even alone raises ``UnreachableBuoyError`` naming it and its shortfall. Reproducible for a seed when the
search stops at ``max_iterations`` rather than at the time limit.
"""

from __future__ import annotations

import itertools
import time
from dataclasses import dataclass, field

import numpy as np

from planner.chnn_ga import GAParameters
from planner.errors import InputError, UnreachableBuoyError
from planner.local_search import iterated_local_search, local_search, neighbour_lists
from planner.sortie_cost import EnergyBudget, SortieCost, default_sortie_cost
from planner.sortie_search import copy_solution, refresh, search, seed_rng, total_cost
from planner.sortie_search import local_search as sortie_local_search
from planner.split import folded_matrices, split_tour
from planner.tour import plan_tour

OBJECTIVES = ("time", "distance")
REOPTIMISE_EXACT_MAX_BUOYS = 11  # Held-Karp on 12 nodes takes a few ms; larger sorties get the CHNN-GA
# The CHNN's initial population costs ~50 ms per sortie whatever the limit: with less time per sortie than this
# the same memetic GA runs without the CHNN (planner/README.md: as good, faster), so the limit holds.
REOPTIMISE_CHNN_MIN_S = 0.1


@dataclass(frozen=True)
class SortieSearchParameters:
    """Settings of the improvement phase; every field is data."""

    neighbours: int = 20  # candidate list of the local search
    ruin_neighbours: int = 60  # SISR's adjacency list (the seed buoy's nearest)
    mean_removed: float = 10.0  # SISR's c-bar: average buoys removed per ruin
    max_string: int = 10  # SISR's L-max: longest removed string
    blink: float = 0.01  # SISR's blink rate during insertion
    temp_start: float = 0.3  # SA temperature at the start and the end, in units of the mean arc cost
    temp_end: float = 0.003
    local_search: bool = True  # local search after every recreate (SISR alone when False)
    chunk_s: float = 0.02  # the numba loop returns to Python to read the clock about this often
    reoptimise_s_per_sortie: float = 0.01  # time kept at the end for the per-sortie re-optimisation (~8 ms each)


@dataclass
class SortiePlan:
    """Sorties from the depot (each a list of buoy node indices, in flying order) and what they cost."""

    sorties: list[list[int]]
    objective: str
    cost: float  # the objective's total: seconds (time) or metres (distance)
    time_s: list[float]
    energy_wh: list[float]
    distance_m: list[float]
    elapsed_s: float
    iterations: int
    split_cost: float  # the objective after route-first cluster-second, before the improvement
    history: list[dict] = field(default_factory=list)  # best objective over time

    @property
    def total_time_s(self) -> float:
        return float(sum(self.time_s))

    @property
    def total_distance_m(self) -> float:
        return float(sum(self.distance_m))


def check_reachable(cost: SortieCost) -> None:
    """UnreachableBuoyError for every buoy that even a sortie of its own cannot serve within the budget."""
    alone = cost.alone_energy_wh()
    bad = np.flatnonzero(alone > cost.budget_wh * (1 + 1e-12)).tolist()
    if bad:
        raise UnreachableBuoyError(bad, alone[bad].tolist(), cost.budget_wh)


def objective_matrices(cost: SortieCost, objective: str) -> tuple[np.ndarray, np.ndarray, float, float]:
    """Arc cost C and arc energy E with services folded in, the fixed cost per sortie and the energy capacity
    left for the arcs (budget less the fixed per-sortie energy)."""
    if objective == "time":
        leg, node, fixed = cost.leg_time_s, cost.dwell_time_s.copy(), cost.sortie_time_s
    elif objective == "distance":
        leg, node, fixed = cost.leg_distance_m, np.zeros(cost.n), 0.0
    else:
        raise InputError(f"unknown objective {objective!r}; use one of {', '.join(OBJECTIVES)}")
    node[0] = 0.0
    energy_node = cost.dwell_energy_wh.copy()
    energy_node[0] = 0.0
    C, E = folded_matrices(leg, node, cost.leg_energy_wh, energy_node)
    return C, E, float(fixed), float(cost.budget_wh - cost.sortie_energy_wh)


def giant_tour(C: np.ndarray, method: str, seed: int, time_limit_s: float) -> np.ndarray:
    """A closed tour through the depot and every buoy on the symmetrised arc costs (the direction is chosen by
    the split), starting at the depot."""
    sym = np.ascontiguousarray((C + C.T) / 2.0)
    if method == "chnn-ga":
        return np.asarray(plan_tour(distance=sym, seed=seed, time_limit_s=time_limit_s).order, dtype=np.int64)
    if method != "ils":
        raise InputError(f"unknown giant tour method {method!r}; use ils or chnn-ga")
    n = len(sym)
    tour = np.random.default_rng(seed).permutation(n).astype(np.int64)
    neighbours = neighbour_lists(sym, 10)
    local_search(tour, sym, neighbours)
    iterated_local_search(tour, sym, neighbours, max(30, n), 50, seed)
    return np.roll(tour, -int(np.flatnonzero(tour == 0)[0]))


# The working solution's eight arrays, spelled out: the kernels take positional arguments after them, which mypy
# accepts only after a star-argument of known length.
_Working = tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray]


class _Search:
    """One instance's arrays for the numba kernels (planner.sortie_search): the arc matrices, the candidate
    lists, and the working, current and best solutions."""

    def __init__(self, C, E, fixed: float, cap: float, sorties: list[list[int]], params: SortieSearchParameters):
        n = len(C)
        self.problem = (C, E, fixed, cap)
        self.neighbours = buoy_neighbours(C, params.neighbours)
        self.adjacency = buoy_neighbours(C, params.ruin_neighbours)
        self.params = params
        self.routes = np.zeros((n, n + 2), dtype=np.int64)
        self.rlen = np.zeros(n, dtype=np.int64)
        self.info = np.zeros(2, dtype=np.int64)  # [routes in use, move counter]
        self.route_of = np.zeros(n, dtype=np.int64)
        self.pos = np.zeros(n, dtype=np.int64)
        self.pref = np.zeros((4, n, n + 2))
        self.stamp = np.zeros(n, dtype=np.int64)
        self.tested = np.full(n, -1, dtype=np.int64)
        self.buf = np.zeros((2, n + 2), dtype=np.int64)
        for r, sortie in enumerate(sorties):
            self.routes[r, : len(sortie) + 2] = [0, *sortie, 0]
            self.rlen[r] = len(sortie) + 2
            refresh(r, self.routes, self.rlen, self.route_of, self.pos, self.pref, C, E)
        self.info[0] = len(sorties)
        self.cur = (self.routes.copy(), self.rlen.copy(), self.info.copy())
        self.best = (self.routes.copy(), self.rlen.copy(), self.info.copy())
        self.costs = np.zeros(2)  # [current, best]

    @property
    def _working(self) -> _Working:
        return (self.routes, self.rlen, self.info, self.route_of, self.pos, self.pref, self.stamp, self.tested)

    def local_search(self) -> float:
        """Local search of the working solution, which then becomes the current and the best one."""
        sortie_local_search(*self.problem, self.neighbours, *self._working, self.buf)
        copy_solution(self.routes, self.rlen, self.info, *self.cur)
        copy_solution(self.routes, self.rlen, self.info, *self.best)
        cost = total_cost(self.pref, self.rlen, self.info, self.problem[2])
        self.costs[:] = cost
        return cost

    def anneal(self, iterations: int, temp_start: float, temp_end: float) -> None:
        """Rounds of ruin, recreate and local search with the annealing acceptance (sortie_search.search)."""
        p = self.params
        search(*self.problem, self.neighbours, self.adjacency, *self._working, self.buf, *self.cur, *self.best,
               self.costs, iterations, temp_start, temp_end, p.mean_removed, p.max_string, p.blink,
               p.local_search)  # fmt: skip

    def best_sorties(self) -> list[list[int]]:
        routes, rlen, info = self.best
        return [routes[r, 1 : rlen[r] - 1].tolist() for r in range(info[0])]


def _arcs(route: list[int], M: np.ndarray) -> float:
    """Sum of M over the arcs of the sortie 0 -> route -> 0."""
    return float(sum(M[a, b] for a, b in itertools.pairwise([0, *route, 0])))


def reoptimise_sortie(
    sortie: list[int], C: np.ndarray, E: np.ndarray, cap: float, seed: int, limit_s: float
) -> list[int]:
    """The single-sortie planner on one sortie's buoys (Held-Karp when small: exact for asymmetric costs too;
    else the CHNN-GA on the symmetrised costs, then the better direction on the true ones); the planned order
    is kept only if cheaper and within the budget. limit_s is this sortie's share of the time."""
    nodes = np.array([0, *sortie])
    if len(sortie) < 3:
        candidates = [sortie, sortie[::-1]]
    else:
        sub = C[np.ix_(nodes, nodes)]
        if len(sortie) <= REOPTIMISE_EXACT_MAX_BUOYS:
            order = plan_tour(distance=sub, method="exact").order
        else:
            ga = None if limit_s >= REOPTIMISE_CHNN_MIN_S else GAParameters(use_chnn=False)
            order = plan_tour(distance=(sub + sub.T) / 2.0, seed=seed, time_limit_s=limit_s, ga=ga).order
        planned = nodes[order[1:]].tolist()
        candidates = [sortie, planned, planned[::-1]]
    feasible = [r for r in candidates if _arcs(r, E) <= cap]
    return min(feasible, key=lambda r: _arcs(r, C))


def _temperatures(mean_arc: float, params: SortieSearchParameters, progress: float, progress_end: float):
    """The annealing temperature at two points of the run's progress (0..1): geometric from temp_start to
    temp_end, in units of the mean arc."""
    ratio = params.temp_end / params.temp_start
    return mean_arc * params.temp_start * ratio**progress, mean_arc * params.temp_start * ratio**progress_end


def plan_sorties(
    cost: SortieCost,
    objective: str = "time",
    seed: int = 0,
    time_limit_s: float = 2.0,
    max_iterations: int | None = None,
    giant_tour_method: str = "ils",
    reoptimise: bool = True,
    params: SortieSearchParameters | None = None,
) -> SortiePlan:
    """Sorties covering every buoy of ``cost`` once, each within its budget, minimising the objective.

    Stops at time_limit_s (wall clock, the whole call) or after max_iterations ruin-and-recreate rounds,
    whichever comes first; with max_iterations (and time to spare) the result depends on the seed only.
    Raises UnreachableBuoyError and InputError (bad objective or limits)."""
    started = time.perf_counter()
    params = params or SortieSearchParameters()
    if not (isinstance(time_limit_s, int | float) and np.isfinite(time_limit_s) and time_limit_s > 0):
        raise InputError(f"time limit must be a positive number of seconds, got {time_limit_s!r}")
    C, E, fixed, cap = objective_matrices(cost, objective)
    check_reachable(cost)
    n = cost.n
    # 1-2: route first, cluster second (the giant tour's direction matters with wind: split both)
    tour = giant_tour(C, giant_tour_method, seed, 0.1 * time_limit_s)[1:]
    sorties, split_cost = min((split_tour(t, C, E, fixed, cap) for t in (tour, tour[::-1])), key=lambda s: s[1])
    # 3: local search, then ruin-and-recreate rounds under the annealing schedule
    seed_rng(seed)
    state = _Search(C, E, fixed, cap, sorties, params)
    first = state.local_search()
    services = float(C[0, 1:].sum() - (cost.leg_time_s if objective == "time" else cost.leg_distance_m)[0, 1:].sum())
    mean_arc = max((first - fixed * state.info[0] - services) / (n - 1 + state.info[0]), 1e-9)
    history = [{"elapsed_s": time.perf_counter() - started, "iterations": 0, "best": first}]
    kept = params.reoptimise_s_per_sortie * state.info[0] if reoptimise else 0.0
    search_end = max(time_limit_s - kept, 0.5 * time_limit_s)
    iterations = 0
    if n > 3:
        iterations = run_rounds(state.anneal, lambda: float(state.costs[1]), started, search_end, max_iterations,
                                mean_arc, params, history)  # fmt: skip
    best = state.best_sorties()
    # 4: each sortie's order by the single-sortie planner
    if reoptimise:
        share = max(1e-3, time_limit_s - (time.perf_counter() - started)) / max(1, len(best))
        best = [reoptimise_sortie(s, C, E, cap, seed, share) for s in best]
    return _plan(cost, best, objective, C, fixed, split_cost, iterations, history, started)


def run_rounds(anneal, best_cost, started: float, search_end: float, max_iterations: int | None, mean_arc: float,
               params: SortieSearchParameters, history: list[dict]) -> int:  # fmt: skip
    """Ruin-and-recreate rounds until ``search_end`` seconds after ``started`` or ``max_iterations`` rounds,
    whichever comes first; returns the rounds run. ``anneal(rounds, temp_from, temp_to)`` runs a chunk of rounds
    (a numba kernel), ``best_cost()`` reads the best objective so far: each improvement is appended to history.
    With max_iterations the annealing schedule follows the rounds (reproducible), else the clock; the chunk
    aims at params.chunk_s per call, so the clock is read often enough."""
    iterations, chunk = 0, 1
    while max_iterations is None or iterations < max_iterations:
        elapsed = time.perf_counter() - started
        if elapsed >= search_end:
            break
        if max_iterations is not None:  # the schedule follows the rounds: reproducible
            chunk = min(chunk, max_iterations - iterations)
            progress, progress_end = iterations / max_iterations, (iterations + chunk) / max_iterations
        else:  # the schedule follows the clock
            progress, progress_end = elapsed / search_end, min(1.0, (elapsed + params.chunk_s) / search_end)
        tick = time.perf_counter()
        anneal(chunk, *_temperatures(mean_arc, params, progress, progress_end))
        iterations += chunk
        if max_iterations is None:  # aim at chunk_s per call
            chunk = max(1, int(chunk * min(2.0, params.chunk_s / max(time.perf_counter() - tick, 1e-6))))
        if best_cost() < history[-1]["best"] - 1e-9:
            now = time.perf_counter() - started
            history.append({"elapsed_s": now, "iterations": iterations, "best": best_cost()})
    return iterations


def warm_up() -> None:
    """Compile (or load from the on-disk cache) every kernel of the search on a tiny instance: the first call
    otherwise spends its time limit compiling."""
    rng = np.random.default_rng(0)
    points = np.vstack([[0.0, 0.0], rng.uniform(-500.0, 500.0, (12, 2))])
    cost = default_sortie_cost(points, EnergyBudget(12.0, reserve=0.0))
    plan_sorties(cost, seed=0, time_limit_s=600.0, max_iterations=3)


def buoy_neighbours(C: np.ndarray, k: int) -> np.ndarray:
    """Each node's k nearest buoys by the symmetrised arc cost (never the depot; row 0 is unused)."""
    n = len(C)
    if n <= 2:
        return np.ones((n, 1), dtype=np.int64)  # one buoy: no pair to try (a pair (1, 1) is never a move)
    keyed = C + C.T
    keyed[:, 0] = np.inf
    return neighbour_lists(keyed, min(k, n - 2))


def _plan(cost: SortieCost, sorties, objective, C, fixed, split_cost, iterations, history, started) -> SortiePlan:
    problems = cost.violations(sorties)
    assert not problems, f"the sortie planner returned an invalid plan: {problems}"  # a bug, never bad input
    total = sum(fixed + sum(C[a, b] for a, b in zip([0, *s], [*s, 0], strict=True)) for s in sorties)
    return SortiePlan(
        sorties=sorties,
        objective=objective,
        cost=float(total),
        time_s=[cost.time_s(s) for s in sorties],
        energy_wh=[cost.energy_wh(s) for s in sorties],
        distance_m=[cost.distance_m(s) for s in sorties],
        elapsed_s=time.perf_counter() - started,
        iterations=iterations,
        split_cost=split_cost,
        history=history,
    )
