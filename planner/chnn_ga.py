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

Seeded and reproducible for a given seed and generation count; anytime: it stops at the time limit or after
a number of generations without a shorter tour (``stall_generations``, more for more nodes), and returns the
best tour found so far.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field

import numpy as np

from planner import chnn
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
) -> tuple[list[np.ndarray], dict]:
    """Algorithm 2's start: the CHNN from random states (small missions) or random tours (large ones, where
    an n^2-neuron network is too slow). An invalid network state is replaced by a random tour."""
    n = len(dist)
    m = n - 1
    info: dict = {"chnn_children": 0, "chnn_valid": 0, "energy": []}
    tours: list[np.ndarray | None] = [None] * size
    if ga.use_chnn and 2 <= m <= ga.initial_chnn_max:
        free = np.arange(1, n)
        d, d_start, d_end = chnn.normalised(dist, free, 0, 0)
        run = chnn.run_chnn(d, d_start, d_end, params, chnn.initial_state(size, m, params, rng))
        for k in range(size):
            order = chnn.decode(run.v[k])
            if order is not None:
                tours[k] = np.concatenate([[0], free[order]]).astype(np.int64)
        info.update(chnn_children=size, chnn_valid=sum(t is not None for t in tours))
        info["energy"] = run.energy[:, 0].tolist()
        valid = [k for k in range(size) if tours[k] is not None]
        if valid:
            info["chnn_best_length"] = min(tour_length(tours[k], dist) for k in valid)
    return [t if t is not None else rng.permutation(n).astype(np.int64) for t in tours], info


def chnn_ga(
    dist: np.ndarray,
    seed: int = 0,
    time_limit_s: float = 2.0,
    ga: GAParameters | None = None,
    params: chnn.CHNNParameters = chnn.VALID_TOURS,
) -> GAResult:
    """Best closed tour found by the memetic CHNN-GA within the time limit (node 0 first)."""
    ga = ga or GAParameters()
    started = time.perf_counter()
    n = len(dist)
    dist = np.ascontiguousarray(dist, dtype=float)
    if n <= 3:
        order = list(range(n))
        return GAResult(order, float(tour_length(np.arange(n), dist)), [])
    rng = np.random.default_rng(seed)
    size = ga.population if n <= 150 else max(2, ga.population // 2)
    neighbours = neighbour_lists(dist, ga.neighbours)
    kicks = ga.ils_kicks or max(30, n)

    population, info = _initial_population(dist, size, ga, params, rng)
    lengths = np.array([local_search(t, dist, neighbours) for t in population])
    best = int(np.argmin(lengths))
    best_tour, best_length = population[best].copy(), float(lengths[best])
    history = [
        {
            "generation": 0,
            "best_length": best_length,
            "mean_length": float(lengths.mean()),
            "elapsed_s": time.perf_counter() - started,
            **info,
        }
    ]
    stall = 0
    generation = 0
    stall_limit = max(ga.stall_generations, int(ga.stall_per_node * n))
    while stall < stall_limit and time.perf_counter() - started < time_limit_s:
        generation += 1
        operator = rng.random(size)
        use_chnn = ga.use_chnn & (operator < ga.p_chnn)
        use_cx = (operator >= ga.p_chnn) & (operator < ga.p_chnn + ga.p_crossover)
        chnn_idx = np.flatnonzero(use_chnn)
        children: list[np.ndarray | None] = [None] * size
        energy_trace: list[float] = []
        if len(chnn_idx):
            made, trace = _chnn_children([population[k] for k in chnn_idx], dist, ga, params, rng)
            for k, child in zip(chnn_idx, made, strict=True):
                children[k] = child
            energy_trace = trace.tolist()
        accepted = {"chnn": 0, "crossover": 0, "ils": 0}
        for k in range(size):
            if time.perf_counter() - started >= time_limit_s:
                break  # anytime: the rest of this generation keeps its parents
            if use_chnn[k]:
                kind, child = "chnn", children[k]
                if child is None:
                    continue  # invalid network state: Algorithm 2 keeps the parent (line 13)
                length = local_search(child, dist, neighbours)
            elif use_cx[k]:
                kind = "crossover"
                other = population[int(rng.choice(np.delete(np.arange(size), k)))] if size > 1 else best_tour
                child = _order_crossover(population[k], other, rng)
                length = local_search(child, dist, neighbours)
            else:
                kind, child = "ils", population[k].copy()
                length = iterated_local_search(child, dist, neighbours, kicks, ga.ils_segment, int(rng.integers(2**31)))
            if length < lengths[k] - 1e-9:  # Algorithm 2, line 9: shorter (and valid, by construction)
                population[k], lengths[k] = child, length
                accepted[kind] += 1
        improved = float(lengths.min()) < best_length - 1e-9
        if improved:
            best = int(np.argmin(lengths))
            best_tour, best_length = population[best].copy(), float(lengths[best])
        stall = 0 if improved else stall + 1
        history.append(
            {
                "generation": generation,
                "best_length": best_length,
                "mean_length": float(lengths.mean()),
                "elapsed_s": time.perf_counter() - started,
                "chnn_children": len(chnn_idx),
                "chnn_valid": sum(children[k] is not None for k in chnn_idx),
                "accepted": accepted,
                "energy": energy_trace,
            }
        )
    return GAResult(_rotate_to_depot(best_tour), float(tour_length(best_tour, dist)), history)
