"""Prins' exact split: the best cut of a giant tour into sorties that each fit one battery.

Route-first, cluster-second (Beasley 1983; Prins 2004, "A simple and effective evolutionary algorithm for the
vehicle routing problem", Section 3): given the buoys in one order t_1..t_m, every sortie must be a stretch
t_i..t_j of it. Bellman's recursion over the prefixes

    V_0 = 0,    V_j = min over i <= j with energy(t_i..t_j) <= budget of  V_{i-1} + cost(t_i..t_j)

is a shortest path in the DAG whose arc (i-1, j) is the sortie 0 -> t_i -> ... -> t_j -> 0, so V_m is the
best split of that order. Energies are non-negative, so for each i the stretch grows until it no longer fits:
O(m k) work for sorties of at most k buoys. Costs and energies may be asymmetric (the giant tour's direction
is the flying direction).

The matrices here have each node's service (dwell) folded into the arcs that arrive at it (see
``folded_matrices``), so a sortie's cost is the sum of its arcs plus the fixed per-sortie part.
"""

from __future__ import annotations

import numpy as np

from uavcore.kernel_cache import cached_kernel


@cached_kernel
def split_kernel(tour, C, E, fixed_cost, capacity):
    """Bellman's split of ``tour`` (buoys only, no depot): returns (V, pred) with V[j] the best cost of the
    first j buoys and pred[j] the index where the last sortie of that best split starts. V[m] = inf when no
    split fits (some buoy is unreachable alone)."""
    m = len(tour)
    V = np.full(m + 1, np.inf)
    pred = np.full(m + 1, -1, dtype=np.int64)
    V[0] = 0.0
    for i in range(1, m + 1):
        if V[i - 1] == np.inf:
            continue
        first = tour[i - 1]
        cost = C[0, first]
        energy = E[0, first]
        for j in range(i, m + 1):
            last = tour[j - 1]
            if j > i:
                prev = tour[j - 2]
                cost += C[prev, last]
                energy += E[prev, last]
            if energy + E[last, 0] > capacity:
                break
            total = V[i - 1] + fixed_cost + cost + C[last, 0]
            if total < V[j]:
                V[j] = total
                pred[j] = i - 1
    return V, pred


def split_tour(tour, C: np.ndarray, E: np.ndarray, fixed_cost: float, capacity: float) -> tuple[list[list[int]], float]:
    """The best split of the buoy order ``tour`` into sorties (lists of buoys) and its total cost; capacity
    is the energy budget left after the fixed per-sortie energy. ([], inf) when no split fits."""
    tour = np.ascontiguousarray(tour, dtype=np.int64)
    V, pred = split_kernel(tour, C, E, float(fixed_cost), float(capacity))
    m = len(tour)
    if not np.isfinite(V[m]):
        return [], float("inf")
    sorties = []
    j = m
    while j > 0:
        i = int(pred[j])
        sorties.append(tour[i:j].tolist())
        j = i
    return sorties[::-1], float(V[m])


def folded_matrices(
    leg_cost: np.ndarray, node_cost: np.ndarray, leg_energy: np.ndarray, node_energy: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """Arc matrices with each node's service added to the arcs that arrive at it: C[i, j] = c_ij + s_j.
    Every node of a sortie is arrived at exactly once, so the sum of a sortie's arcs is its legs plus its
    services, whatever the order; the depot's service is 0."""
    C = np.ascontiguousarray(leg_cost + node_cost[None, :], dtype=np.float64)
    E = np.ascontiguousarray(leg_energy + node_energy[None, :], dtype=np.float64)
    np.fill_diagonal(C, 0.0)
    np.fill_diagonal(E, 0.0)
    return C, E
