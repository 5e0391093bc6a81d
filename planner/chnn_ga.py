"""CHNN-GA, paper Section V-C, Algorithm 2, made memetic.

Algorithm 2 keeps a population of tours. Each generation every parent gets one child; the child replaces its
parent only if it is a valid tour and shorter (lines 9-14); the best tour ever seen is the answer. The CHNN is
the generator and the mutation operator: the initial population is the CHNN run from random states, and a
"CHNN child" is the network re-run from its parent's permutation matrix plus noise (the "input of the next
CHNN", line 11) over a window of up to ``window`` consecutive buoys with the window's neighbours clamped (the
whole tour with the depot clamped when the mission is that small). Two operators are added because the CHNN
alone is a weak optimiser: order crossover (OX) with another member, and an iterated local search chain
(segment-local double-bridge kicks). Every child is repaired with 2-opt + Or-opt before it competes: that
memetic repair is where most of the quality comes from (bench/planner_bench.py measures the CHNN's share).
Two options let the CHNN contribute as a prior on edges instead (planner.chnn_guidance): CHNN partners in the
local search's candidate lists, and an edge crossover weighted by the CHNN's edge frequencies; both are off by
default (bench/chnn_contribution.py measures them; planner/README.md has the verdict).

Seeded and reproducible for a given seed and generation count; anytime: it stops at the time limit or after
a number of generations without a shorter tour (``stall_generations``, more for more nodes), and returns the
best tour found so far.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field

import numpy as np

from planner import chnn
from planner.chnn_guidance import Windows, edge_frequencies, guided_neighbour_lists, neighbourhood_edge_frequencies
from planner.edge_crossover import edge_crossover
from planner.local_search import iterated_local_search, local_search, neighbour_lists, tour_length


@dataclass(frozen=True)
class GAParameters:
    """Settings of the memetic CHNN-GA; every field is data, none is hidden in the code."""

    population: int = 8  # individuals (halved past 150 nodes so each ILS chain gets more time)
    window: int = 16  # buoys re-optimised by one CHNN mutation (the whole mission if it has no more)
    initial_chnn_max: int = 30  # the initial population comes from the CHNN up to this many buoys
    chnn_steps: int = 100  # Euler steps of a CHNN mutation (it starts near a corner, so it settles fast)
    parent_bias: float = 1.0  # +-bias on the parent's neurons in the mutation's initial state, in units of u0
    p_chnn: float = 0.4  # share of children made by the CHNN mutation
    p_crossover: float = 0.3  # share made by order crossover; the rest by an ILS chain
    ils_kicks: int = 0  # kicks per ILS child; 0 = one per node (at least 30)
    ils_segment: int = 50  # longest stretch moved by a double-bridge kick
    neighbours: int = 10  # candidate list length for 2-opt / Or-opt
    stall_generations: int = 5  # stop after max(this, stall_per_node x n) generations without a shorter tour
    stall_per_node: float = 0.3
    use_chnn: bool = True  # False = the same memetic GA with random tours and no CHNN (ablation)
    # The CHNN as a prior on edges (planner.chnn_guidance); both off = the paper's way. Measured in
    # bench/chnn_contribution.py (see planner/README.md for the verdict).
    chnn_candidates: int = 0  # slots of each candidate list given to the node's likeliest CHNN partners
    edge_crossover: bool = False  # edge crossover weighted by the CHNN's edge frequencies instead of OX
    # (with use_chnn=False the edge crossover runs with a zero prior: the control without the CHNN)


@dataclass
class GAResult:
    order: list[int]  # starts at node 0
    length: float
    history: list[dict] = field(default_factory=list)


def _rotate_to_depot(tour: np.ndarray) -> list[int]:
    start = int(np.flatnonzero(tour == 0)[0])
    return np.roll(tour, -start).tolist()


def _order_crossover(first: np.ndarray, second: np.ndarray, rng: np.random.Generator) -> np.ndarray:
    """OX: keep a random stretch of the first parent, fill the rest in the second parent's cyclic order."""
    n = len(first)
    i, j = sorted(rng.choice(n + 1, size=2, replace=False))
    kept = first[i:j]
    taken = np.zeros(n, dtype=bool)
    taken[kept] = True
    where = int(np.flatnonzero(second == first[j - 1])[0])
    rest = np.roll(second, -(where + 1))
    return np.concatenate([kept, rest[~taken[rest]]]).astype(np.int64)


def _chnn_children(
    parents: list[np.ndarray],
    dist: np.ndarray,
    ga: GAParameters,
    params: chnn.CHNNParameters,
    rng: np.random.Generator,
) -> tuple[list[np.ndarray | None], np.ndarray]:
    """Re-run the CHNN on a window of each parent's tour; None where the network ended on an invalid state.
    Returns the children and the energy trace of the first network."""
    n = len(dist)
    w = min(ga.window, n - 1)
    batch = len(parents)
    d = np.empty((batch, w, w))
    d_start = np.empty((batch, w))
    d_end = np.empty((batch, w))
    windows = []
    for k, tour in enumerate(parents):
        # the whole mission fits: clamp the depot (the paper's setting); else a random stretch
        s = int(np.flatnonzero(tour == 0)[0]) if w == n - 1 else int(rng.integers(n))
        positions = (s + np.arange(w + 2)) % n
        start, free, end = tour[positions[0]], tour[positions[1:-1]], tour[positions[-1] % n]
        d[k], d_start[k], d_end[k] = chnn.normalised(dist, free, start, end)
        windows.append((positions[1:-1], free))
    mutation = chnn.with_steps(params, ga.chnn_steps)
    parent_rows = np.tile(np.arange(w), (batch, 1))  # each window's buoys are listed in the parent's order
    u_init = chnn.initial_state(batch, w, mutation, rng, parents=parent_rows, parent_bias=ga.parent_bias * params.u0)
    run = chnn.run_chnn(d, d_start, d_end, mutation, u_init)
    children: list[np.ndarray | None] = []
    for k, tour in enumerate(parents):
        order = chnn.decode(run.v[k])
        if order is None:
            children.append(None)
            continue
        child = tour.copy()
        positions, free = windows[k]
        child[positions] = free[order]
        children.append(child)
    return children, run.energy[:, 0]


def _initial_population(
    dist: np.ndarray, size: int, ga: GAParameters, params: chnn.CHNNParameters, rng: np.random.Generator
) -> tuple[list[np.ndarray], dict, np.ndarray | None]:
    """Algorithm 2's start: the CHNN from random states (small missions) or random tours (large ones, where
    an n^2-neuron network is too slow). An invalid network state is replaced by a random tour. Also returns
    the networks' final activations (None when no network ran), which the edge prior reuses."""
    n = len(dist)
    m = n - 1
    info: dict = {"chnn_children": 0, "chnn_valid": 0, "energy": []}
    tours: list[np.ndarray | None] = [None] * size
    activations = None
    if ga.use_chnn and 2 <= m <= ga.initial_chnn_max:
        free = np.arange(1, n)
        d, d_start, d_end = chnn.normalised(dist, free, 0, 0)
        run = chnn.run_chnn(d, d_start, d_end, params, chnn.initial_state(size, m, params, rng))
        activations = run.v
        for k in range(size):
            order = chnn.decode(run.v[k])
            if order is not None:
                tours[k] = np.concatenate([[0], free[order]]).astype(np.int64)
        info.update(chnn_children=size, chnn_valid=sum(t is not None for t in tours))
        info["energy"] = run.energy[:, 0].tolist()
        valid = [k for k in range(size) if tours[k] is not None]
        if valid:
            info["chnn_lengths"] = [float(tour_length(tours[k], dist)) for k in valid]  # as decoded, before repair
            info["chnn_best_length"] = min(info["chnn_lengths"])
    population = [t if t is not None else rng.permutation(n).astype(np.int64) for t in tours]
    return population, info, activations


def _edge_prior(
    dist: np.ndarray,
    activations: np.ndarray | None,
    ga: GAParameters,
    params: chnn.CHNNParameters,
    rng: np.random.Generator,
) -> np.ndarray | None:
    """The CHNN's edge frequencies (planner.chnn_guidance) when an option reads them, else None: from the
    initial population's whole-tour networks when they ran, else from a batch of neighbourhood networks of
    ``window`` nodes."""
    if not (ga.use_chnn and (ga.chnn_candidates > 0 or ga.edge_crossover)):
        return None
    n = len(dist)
    if activations is not None:
        return edge_frequencies(activations, Windows.whole_tour(n, len(activations)), n)
    return neighbourhood_edge_frequencies(dist, min(ga.window, n - 1), params, rng)


def _candidate_lists(dist: np.ndarray, prior: np.ndarray | None, ga: GAParameters) -> np.ndarray:
    """Nearest-neighbour lists, or lists that give chnn_candidates slots to the CHNN's likeliest partners."""
    if prior is None or ga.chnn_candidates <= 0:
        return neighbour_lists(dist, ga.neighbours)
    return guided_neighbour_lists(dist, prior, ga.neighbours, ga.chnn_candidates)


def _population_size(n: int, ga: GAParameters) -> int:
    """Individuals in the population: halved past 150 nodes so that each ILS chain gets more of the time."""
    return ga.population if n <= 150 else max(2, ga.population // 2)


def _stall_limit(n: int, ga: GAParameters) -> int:
    """Generations without a shorter tour after which the search stops (more for more nodes)."""
    return max(ga.stall_generations, int(ga.stall_per_node * n))


@dataclass(frozen=True)
class _Run:
    """What every step of one run reads and none changes: the instance, the settings, the clock and the rng."""

    dist: np.ndarray
    neighbours: np.ndarray  # candidate lists for 2-opt / Or-opt
    edge_weight: np.ndarray  # the edge crossover's prior: the CHNN's edge frequencies, or zeros
    ga: GAParameters
    params: chnn.CHNNParameters
    rng: np.random.Generator
    ils_kicks: int
    started: float  # time.perf_counter() at the call
    cpu_started: float  # time.process_time() at the call
    time_limit_s: float

    def elapsed_s(self) -> float:
        return time.perf_counter() - self.started

    def out_of_time(self) -> bool:
        return self.elapsed_s() >= self.time_limit_s

    def repair(self, tour: np.ndarray) -> float:
        """2-opt + Or-opt on the tour in place (the memetic repair); its new length."""
        return local_search(tour, self.dist, self.neighbours)


@dataclass
class _Population:
    """The tours, their lengths, and the best tour seen so far (what Algorithm 2, lines 17-18, returns)."""

    tours: list[np.ndarray]
    lengths: np.ndarray
    best_tour: np.ndarray
    best_length: float

    @classmethod
    def repaired(cls, tours: list[np.ndarray], run: _Run) -> _Population:
        """The population after every tour has been repaired in place by local search."""
        lengths = np.array([run.repair(tour) for tour in tours])
        best = int(np.argmin(lengths))
        return cls(tours, lengths, tours[best].copy(), float(lengths[best]))

    def accept(self, k: int, child: np.ndarray, length: float) -> bool:
        """Algorithm 2, lines 9-14: the child replaces parent k only if it is shorter; every child here is a
        valid tour by construction (an invalid CHNN state never becomes a child)."""
        if length < self.lengths[k] - 1e-9:
            self.tours[k], self.lengths[k] = child, length
            return True
        return False  # line 13: keep the previous generation's tour

    def update_best(self) -> bool:
        """Remember the shortest tour of this generation if it beats the best so far; whether it did."""
        if float(self.lengths.min()) < self.best_length - 1e-9:
            best = int(np.argmin(self.lengths))
            self.best_tour, self.best_length = self.tours[best].copy(), float(self.lengths[best])
            return True
        return False

    def summary(self, generation: int, run: _Run) -> dict:
        """The history entry's common part: best and mean length after this generation, every individual's
        (all feasible tours), time so far."""
        return {
            "generation": generation,
            "best_length": self.best_length,
            "mean_length": float(self.lengths.mean()),
            "lengths": self.lengths.tolist(),
            "elapsed_s": run.elapsed_s(),
            "cpu_s": time.process_time() - run.cpu_started,
        }


def _choose_operators(size: int, run: _Run) -> list[str]:
    """Which operator makes each parent's child: "chnn" (share p_chnn), "crossover" (p_crossover) or "ils"
    (the rest, and the CHNN's share too when the CHNN is switched off)."""
    ga = run.ga
    kinds = []
    for draw in run.rng.random(size):
        if draw < ga.p_chnn:
            kinds.append("chnn" if ga.use_chnn else "ils")
        elif draw < ga.p_chnn + ga.p_crossover:
            kinds.append("crossover")
        else:
            kinds.append("ils")
    return kinds


def _chnn_mutations(
    population: _Population, kinds: list[str], run: _Run
) -> tuple[dict[int, np.ndarray | None], list[float]]:
    """The CHNN children of this generation, made in one batch (Algorithm 2, lines 3-7, from the input of line
    11): parent index -> child tour, or None where the network ended invalid; and the first network's energy."""
    chosen = [k for k, kind in enumerate(kinds) if kind == "chnn"]
    if not chosen:
        return {}, []
    made, energy = _chnn_children([population.tours[k] for k in chosen], run.dist, run.ga, run.params, run.rng)
    return dict(zip(chosen, made, strict=True)), energy.tolist()


def _crossover_child(k: int, population: _Population, run: _Run) -> tuple[np.ndarray, float]:
    """Order crossover (or the edge crossover, GAParameters.edge_crossover) of parent k with another member
    drawn at random (the best tour when k is alone), repaired."""
    others = np.delete(np.arange(len(population.tours)), k)
    mate = population.tours[int(run.rng.choice(others))] if len(others) else population.best_tour
    if run.ga.edge_crossover:
        start = int(run.rng.integers(len(mate)))
        child = edge_crossover(population.tours[k], mate, run.edge_weight, run.dist, run.neighbours, start)
    else:
        child = _order_crossover(population.tours[k], mate, run.rng)
    return child, run.repair(child)


def _ils_child(k: int, population: _Population, run: _Run) -> tuple[np.ndarray, float]:
    """An iterated local search chain (double-bridge kicks + repair) started from parent k."""
    child = population.tours[k].copy()
    seed = int(run.rng.integers(2**31))
    return child, iterated_local_search(child, run.dist, run.neighbours, run.ils_kicks, run.ga.ils_segment, seed)


def _next_generation(population: _Population, run: _Run) -> dict:
    """One pass of Algorithm 2's loop body (lines 3-15): a child per parent, which replaces its parent only if
    it is shorter. Returns the generation's counts for the history."""
    kinds = _choose_operators(len(population.tours), run)
    chnn_children, energy = _chnn_mutations(population, kinds, run)
    accepted = {"chnn": 0, "crossover": 0, "ils": 0}
    child_lengths: list[float] = []  # every valid child's length after repair, accepted or not
    for k, kind in enumerate(kinds):
        if run.out_of_time():
            break  # anytime: the rest of this generation keeps its parents
        if kind == "chnn":
            child = chnn_children[k]
            if child is None:
                continue  # invalid network state: Algorithm 2 keeps the parent (line 13)
            length = run.repair(child)
        elif kind == "crossover":
            child, length = _crossover_child(k, population, run)
        else:
            child, length = _ils_child(k, population, run)
        child_lengths.append(float(length))
        if population.accept(k, child, length):
            accepted[kind] += 1
    return {
        "chnn_children": len(chnn_children),
        "chnn_valid": sum(child is not None for child in chnn_children.values()),
        "accepted": accepted,
        "child_lengths": child_lengths,
        "energy": energy,
    }


def chnn_ga(
    dist: np.ndarray,
    seed: int = 0,
    time_limit_s: float = 2.0,
    ga: GAParameters | None = None,
    params: chnn.CHNNParameters = chnn.VALID_TOURS,
    target_length: float | None = None,
) -> GAResult:
    """Best closed tour found by the memetic CHNN-GA within the time limit (node 0 first); it also stops as
    soon as a tour no longer than ``target_length`` is found (e.g. a known optimum, for time-to-target).

    Algorithm 2 of the paper ("Constructing a Reliable and Feasible Path", Section V-C of *Maritime Buoyage
    Inspection System Based on an Unmanned Aerial Vehicle and Active Disturbance Rejection Control*), and the
    step here that does each line:

         1: initialise the weights A, B, C, D and u0                      params (chnn.VALID_TOURS)
         2: while k_ga do                                                 the loop below (stall / time limit)
         3:   calculate d_xy                                              chnn.normalised, per window
         4:   while k_chnn do                                             chnn.run_chnn ...
         5:     calculate the energy E by Algorithm 1                     ... eq. (14)-(16)
         6:   end while
         7:   calculate the current transposition matrix                  chnn.decode (_initial_population,
         8:   calculate the fitness sum d_xy of the current path            _chnn_mutations), then repair
         9:   if the current path is shorter than the parent and valid    _Population.accept
        10:     replace the previous generation's solution
        11:     calculate the input of the next CHNN                      the parent's tour seeds the mutation
        12:   else
        13:     keep the previous generation's solution
        14:     the input of the CHNN remains unchanged
        15:   end if
        16: end while
        17: obtain the optimal generation                                 _Population.update_best
        18: obtain the feasible and reliable inspection trajectory        GAResult

    Added to the paper's loop (see the module docstring): crossover and ILS children beside the CHNN's
    (_choose_operators), and 2-opt + Or-opt repair of every child before line 9.
    """
    ga = ga or GAParameters()
    started, cpu_started = time.perf_counter(), time.process_time()
    n = len(dist)
    dist = np.ascontiguousarray(dist, dtype=float)
    if n <= 3:
        return GAResult(list(range(n)), float(tour_length(np.arange(n), dist)), [])
    rng = np.random.default_rng(seed)
    tours, initial_info, activations = _initial_population(dist, _population_size(n, ga), ga, params, rng)
    prior = _edge_prior(dist, activations, ga, params, rng)
    run = _Run(
        dist=dist,
        neighbours=_candidate_lists(dist, prior, ga),
        edge_weight=prior if prior is not None else np.zeros_like(dist),
        ga=ga,
        params=params,
        rng=rng,
        ils_kicks=ga.ils_kicks or max(30, n),
        started=started,
        cpu_started=cpu_started,
        time_limit_s=time_limit_s,
    )
    population = _Population.repaired(tours, run)
    history = [{**population.summary(0, run), **initial_info}]
    stall, stall_limit = 0, _stall_limit(n, ga)
    target = -np.inf if target_length is None else target_length + 1e-9
    while stall < stall_limit and not run.out_of_time() and population.best_length > target:
        counts = _next_generation(population, run)
        stall = 0 if population.update_best() else stall + 1
        history.append({**population.summary(len(history), run), **counts})
    best = population.best_tour
    return GAResult(_rotate_to_depot(best), float(tour_length(best, dist)), history)
